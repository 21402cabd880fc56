"""vidsim.io."""
