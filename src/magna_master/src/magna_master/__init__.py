"""MAGNA Master: the `magna` command line, private ROS masters and (later) simulation batches."""
