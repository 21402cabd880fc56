"""vidsim.optim."""
