"""ORCA-3D for MAGNA: the numpy reference (`reference`), the C++ library through ctypes
(`native`), and the shared value types (`model`). The ROS service lives in the
orca3d_server node of this package."""
