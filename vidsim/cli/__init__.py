"""vidsim.cli."""
