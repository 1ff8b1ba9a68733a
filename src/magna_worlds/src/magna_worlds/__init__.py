"""MAGNA's world model: JSON -> volumes -> geometries -> pose sets -> free-space poses and obstacles."""
