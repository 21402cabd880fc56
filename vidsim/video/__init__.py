"""vidsim.video."""
