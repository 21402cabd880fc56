"""vidsim.cloth."""
