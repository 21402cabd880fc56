"""vidsim.gap."""
