"""vidsim.log."""
