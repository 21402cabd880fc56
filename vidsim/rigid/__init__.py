"""vidsim.rigid."""
