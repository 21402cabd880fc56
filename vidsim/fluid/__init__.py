"""vidsim.fluid."""
