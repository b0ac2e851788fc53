import pytest

from ofbe_data.io.gravity import local_gravity, normal_gravity


def test_somigliana_matches_wgs84_equator_and_pole():
    # NIMA TR8350.2: γe = 9.7803253359, γp = 9.8321849378 m/s²
    assert normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-10)
    assert normal_gravity(90.0) == pytest.approx(9.8321849378, abs=1e-9)
    assert normal_gravity(-90.0) == pytest.approx(normal_gravity(90.0), abs=1e-12)


def test_mid_latitude_value_and_free_air_correction():
    # International gravity formula value at 45°: 9.806199 m/s² (WGS-84 normal gravity)
    assert normal_gravity(45.0) == pytest.approx(9.806199, abs=2e-6)
    # Haifa-like site used by the examples: 35 m above the ellipsoid
    g = local_gravity(32.794, 35.0)
    assert g == pytest.approx(normal_gravity(32.794) - 3.086e-6 * 35.0, abs=1e-12)
    assert 9.79 < g < 9.80
