"""Offline voice and keyboard command assistant for running MAGNA missions."""
