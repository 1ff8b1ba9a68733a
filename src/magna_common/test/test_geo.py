"""WGS84 <-> ENU, checked against closed forms that do not go through the module's code path."""
import math

import numpy as np
import pytest

from magna_common.geo import E2, A, ecef_to_geodetic, enu_to_geodetic, geodetic_to_ecef, geodetic_to_enu

SEVILLE = (37.4109, -6.0016, 20.0)
B = A * (1.0 - 1.0 / 298.257223563)  # semi-minor axis


def test_ecef_of_reference_points():
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0, 0.0), [A, 0, 0], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 90.0, 100.0), [0, A + 100.0, 0], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(90.0, 0.0, 0.0), [0, 0, B], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(-90.0, 0.0, 10.0), [0, 0, -B - 10.0], atol=1e-6)


@pytest.mark.parametrize("lat, lon, alt", [(0, 0, 0), (37.4109, -6.0016, 20), (-33.9, 151.2, -30),
                                           (89.9999999, 45, 1000), (90, 0, 5), (-90, 0, 5), (60, 179.9, 9000)])
def test_ecef_round_trip(lat, lon, alt):
    got = ecef_to_geodetic(geodetic_to_ecef(lat, lon, alt))
    assert got[0] == pytest.approx(lat, abs=1e-10)
    if abs(lat) < 90:
        assert got[1] == pytest.approx(lon, abs=1e-10)
    assert got[2] == pytest.approx(alt, abs=1e-6)


def test_origin_is_zero():
    np.testing.assert_allclose(geodetic_to_enu(*SEVILLE, SEVILLE), [0, 0, 0], atol=1e-9)


def test_enu_round_trip():
    for enu in ([0, 0, 0], [1.0, 2.0, 3.0], [-250.0, 1300.0, 45.0], [30000.0, -12000.0, -500.0]):
        lat, lon, alt = enu_to_geodetic(enu, SEVILLE)
        np.testing.assert_allclose(geodetic_to_enu(lat, lon, alt, SEVILLE), enu, atol=1e-6)


def test_a_hundred_thousandth_of_a_degree_north_is_about_1_1_m():
    lat, lon, alt = SEVILLE
    e, n, u = geodetic_to_enu(lat + 1e-5, lon, alt, SEVILLE)
    # Meridian radius of curvature M = a (1 - e2) / (1 - e2 sin^2 lat)^1.5
    m = A * (1.0 - E2) / (1.0 - E2 * math.sin(math.radians(lat)) ** 2) ** 1.5
    assert n == pytest.approx((m + alt) * math.radians(1e-5), rel=1e-6)  # arc at height alt
    assert n == pytest.approx(1.109, abs=0.002)
    assert abs(e) < 1e-9 and abs(u) < 1e-6


def test_a_point_on_the_same_parallel_1000_m_east():
    # On the equator the parallel is a circle of radius a: a point at longitude d lies
    # at east = a sin(d), up = a (cos(d) - 1) in the tangent plane at longitude 0.
    d = 1000.0 / A
    e, n, u = geodetic_to_enu(0.0, math.degrees(d), 0.0, (0.0, 0.0, 0.0))
    assert e == pytest.approx(A * math.sin(d), abs=1e-6)
    assert u == pytest.approx(A * (math.cos(d) - 1.0), abs=1e-6)  # -7.8 cm: the earth curves away
    assert abs(n) < 1e-6
    # At latitude lat the parallel's radius is N cos(lat); the chord tilts north in the local frame.
    lat = math.radians(SEVILLE[0])
    radius = A / math.sqrt(1.0 - E2 * math.sin(lat) ** 2) * math.cos(lat)
    d = 1000.0 / radius
    e, n, u = geodetic_to_enu(SEVILLE[0], SEVILLE[1] + math.degrees(d), 0.0, (SEVILLE[0], SEVILLE[1], 0.0))
    assert e == pytest.approx(radius * math.sin(d), abs=1e-6)
    chord_in = radius * (1.0 - math.cos(d))  # toward the parallel's axis
    assert n == pytest.approx(chord_in * math.sin(lat), abs=1e-6)
    assert u == pytest.approx(-chord_in * math.cos(lat), abs=1e-6)


def test_up_is_altitude_and_east_is_east():
    e, n, u = geodetic_to_enu(SEVILLE[0], SEVILLE[1], SEVILLE[2] + 50.0, SEVILLE)
    assert (e, n, u) == pytest.approx((0, 0, 50.0), abs=1e-6)
    e, _n, _u = geodetic_to_enu(SEVILLE[0], SEVILLE[1] + 1e-4, SEVILLE[2], SEVILLE)
    assert 8.8 < e < 8.9  # 1e-4 deg of longitude at 37.4 deg N
