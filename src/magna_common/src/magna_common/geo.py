"""WGS84 geodetic coordinates <-> a local East-North-Up frame, through ECEF.

Latitude and longitude are in degrees, altitude in metres above the WGS84
ellipsoid (as sensor_msgs/NavSatFix says). The ENU frame is the tangent plane at
`origin = (lat, lon, alt)`: x east, y north, z up, so the `map` frame of a world
with `origin_geo` is this frame. Exact for any distance, not a flat-earth
approximation: far points drop below the tangent plane (negative up).
"""
from __future__ import annotations

import math

import numpy as np

A = 6378137.0  # m, WGS84 semi-major axis
F = 1.0 / 298.257223563  # WGS84 flattening
E2 = F * (2.0 - F)  # first eccentricity squared


def geodetic_to_ecef(lat: float, lon: float, alt: float) -> np.ndarray:
    phi, lam = math.radians(lat), math.radians(lon)
    n = A / math.sqrt(1.0 - E2 * math.sin(phi) ** 2)  # prime-vertical radius of curvature
    return np.array([(n + alt) * math.cos(phi) * math.cos(lam),
                     (n + alt) * math.cos(phi) * math.sin(lam),
                     (n * (1.0 - E2) + alt) * math.sin(phi)])


def ecef_to_geodetic(ecef) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in ecef)
    r = math.hypot(x, y)
    lam = math.atan2(y, x)
    phi = math.atan2(z, r * (1.0 - E2))  # exact on the ellipsoid, a close start elsewhere
    for _ in range(10):
        # tan(phi) = (z + e2 N sin(phi)) / r: a contraction by about e2, stable at the poles too.
        n = A / math.sqrt(1.0 - E2 * math.sin(phi) ** 2)
        new = math.atan2(z + E2 * n * math.sin(phi), r)
        if abs(new - phi) < 1e-15:
            phi = new
            break
        phi = new
    # Height along the normal, written so it stays exact at the poles (no division by cos(phi)).
    alt = r * math.cos(phi) + z * math.sin(phi) - A * math.sqrt(1.0 - E2 * math.sin(phi) ** 2)
    return math.degrees(phi), math.degrees(lam), alt


def _enu_rotation(origin) -> np.ndarray:
    """Rows: the east, north and up unit vectors at `origin`, in ECEF."""
    phi, lam = math.radians(origin[0]), math.radians(origin[1])
    sp, cp, sl, cl = math.sin(phi), math.cos(phi), math.sin(lam), math.cos(lam)
    return np.array([[-sl, cl, 0.0],
                     [-sp * cl, -sp * sl, cp],
                     [cp * cl, cp * sl, sp]])


def geodetic_to_enu(lat: float, lon: float, alt: float, origin) -> np.ndarray:
    """[east, north, up] in metres of (lat, lon, alt) about origin (lat, lon, alt)."""
    delta = geodetic_to_ecef(lat, lon, alt) - geodetic_to_ecef(*origin)
    return _enu_rotation(origin) @ delta


def enu_to_geodetic(enu, origin) -> tuple[float, float, float]:
    """(lat, lon, alt) of a point [east, north, up] in metres about origin (lat, lon, alt)."""
    ecef = geodetic_to_ecef(*origin) + _enu_rotation(origin).T @ np.asarray(enu, dtype=float)
    return ecef_to_geodetic(ecef)
