"""MAGNA's UAV side: airframes today; the UAV manager lands with its own issue."""
