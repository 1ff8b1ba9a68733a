"""magna_viz: see a mission (rviz scene and replay, plots from the bag and the CSVs, reports)."""
