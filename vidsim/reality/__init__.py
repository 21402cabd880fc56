"""vidsim.reality."""
