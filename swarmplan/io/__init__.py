"""Getting runs out: the MCAP recorder (with Foxglove scene channels) and the episode runner."""
