"""Tools shared by every MAGNA package; this package imports nothing of MAGNA."""
