"""vidsim.render."""
