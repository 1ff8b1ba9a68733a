"""A forward-looking depth camera on a UAV, rendered by pybullet's CPU (tiny) renderer.

Conventions:
  * the camera sits at `mount_offset` in the body frame and looks along body +x,
    with image up = body +z, so image right = body -y;
  * `fov_deg` is the horizontal field of view (as Gazebo's horizontal_fov); the
    vertical one follows from the aspect ratio with square pixels;
  * `render` returns a float32 (height, width) image as a sensor_msgs/Image of
    encoding 32FC1 wants it (REP 118): row 0 at the top, column 0 at the left, and
    each pixel the metric depth along the optical axis (z-depth, not the range
    along the pixel's ray), +inf where nothing lies between `near` and `far`.

The tiny renderer culls back faces, so a camera inside its own UAV's body (the
default mount is 5 cm above the bottom centre) sees out through it. It draws the
visual shapes; bodies created without one are drawn from their collision shapes.
Geometry nearer than `near` is clipped away, so nothing reads closer than `near`,
but a surface within `near` of the lens is not seen (what lies behind it is).
"""
from __future__ import annotations

import math

import numpy as np
import pybullet as p


class DepthCamera:
    def __init__(self, client: int, width: int = 64, height: int = 48, fov_deg: float = 90.0,
                 near: float = 0.1, far: float = 20.0, mount_offset=(0.0, 0.0, 0.05)):
        if width < 1 or height < 1:
            raise ValueError(f"width, height: must be 1 pixel or more, got {width} x {height}")
        if not 0.0 < fov_deg < 180.0:
            raise ValueError(f"fov_deg: the horizontal field of view must be between 0 and 180 degrees, got {fov_deg}")
        if not 0.0 < near < far:
            raise ValueError(f"near, far: need 0 < near < far, got near={near}, far={far}")
        self.client = client
        self.width, self.height = int(width), int(height)
        self.near, self.far = float(near), float(far)
        self.mount_offset = np.asarray(mount_offset, dtype=float)
        tan_half_h = math.tan(math.radians(fov_deg) / 2.0)
        self.fov_deg = float(fov_deg)
        self.vertical_fov_deg = math.degrees(2.0 * math.atan(tan_half_h * self.height / self.width))
        # Pinhole intrinsics for sensor_msgs/CameraInfo (pixel centres at integer coordinates).
        self.fx = self.fy = (self.width / 2.0) / tan_half_h
        self.cx, self.cy = (self.width - 1) / 2.0, (self.height - 1) / 2.0
        projection = list(p.computeProjectionMatrixFOV(self.vertical_fov_deg, self.width / self.height,
                                                       self.near, self.far))
        # The tiny renderer samples each pixel at its corner, not its centre: shift the image by half a
        # pixel (column-major entries (0, 2) and (1, 2)) so the optical axis meets the image centre (cx, cy).
        projection[8] += 1.0 / self.width
        projection[9] += 1.0 / self.height
        self._projection = projection

    def camera_pose(self, position, orientation_xyzw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Eye position, optical axis and image-up direction in the world frame."""
        rotation = np.array(p.getMatrixFromQuaternion(list(orientation_xyzw))).reshape(3, 3)
        eye = np.asarray(position, dtype=float) + rotation @ self.mount_offset
        return eye, rotation[:, 0], rotation[:, 2]

    def render(self, position, orientation_xyzw) -> np.ndarray:
        """Depth image (height, width) in metres for a body at `position` with `orientation_xyzw`."""
        eye, forward, up = self.camera_pose(position, orientation_xyzw)
        view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), up.tolist())
        _w, _h, _rgb, buffer, segmentation = p.getCameraImage(
            self.width, self.height, viewMatrix=view, projectionMatrix=self._projection,
            renderer=p.ER_TINY_RENDERER, physicsClientId=self.client)
        buffer = np.asarray(buffer, dtype=np.float64).reshape(self.height, self.width)
        # The buffer holds the non-linear OpenGL depth d in [0, 1]; invert the projection:
        # z = far * near / (far - (far - near) * d).
        depth = self.far * self.near / (self.far - (self.far - self.near) * buffer)
        np.maximum(depth, self.near, out=depth)  # float rounding only: the renderer clips nearer geometry
        empty = np.asarray(segmentation).reshape(self.height, self.width) < 0  # no body under this pixel
        depth[empty] = np.inf
        return depth.astype(np.float32)
