"""vidsim.report."""
