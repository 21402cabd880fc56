"""vidsim.config."""
