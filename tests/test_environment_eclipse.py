"""Earth shadow models (adcs_core.environment.eclipse, Montenbruck & Gill 2000 section 3.4.2) on closed
forms: the anti-Sun line is umbra, the Sun side is lit, the conical fraction is continuous in [0, 1],
its penumbra spans exactly the Sun's apparent diameter in the separation angle, the Sun centred on the
Earth's limb is half lit, the annular case beyond the umbra's apex is 1 - b^2/a^2, and the eclipse
fraction of an orbit with the Sun in its plane is asin(R_E / r) / pi."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adcs_core.environment import eclipse as E
from adcs_core.environment.sun import AU, SUN_RADIUS

R_LEO = E.EARTH_RADIUS + 500e3
SUN = np.array([AU, 0.0, 0.0])


def _ring(theta):
    """Positions on a LEO circle in the plane containing the Sun (theta from the Sun direction)."""
    return R_LEO * np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=-1)


@pytest.mark.parametrize('shadow', [E.shadow_cylindrical, E.shadow_conical])
def test_anti_sun_line_is_umbra_and_sun_side_is_lit(shadow):
    assert shadow(np.array([-R_LEO, 0, 0]), SUN) == 0.0
    assert shadow(np.array([R_LEO, 0, 0]), SUN) == 1.0
    assert shadow(np.array([0, R_LEO, 0]), SUN) == 1.0                   # terminator plane, 500 km up
    assert shadow(np.array([-R_LEO, 0, 0.9 * E.EARTH_RADIUS]), SUN) == 0.0


def test_conical_fraction_is_continuous_in_unit_interval_and_monotone_through_entry():
    """Sweep the shadow entry in steps of 1e-5 rad: values in [0, 1], non-increasing into the shadow,
    no jump larger than the slope allows (penumbra ~8 s of a 95-min orbit: ~1000 samples, steps < 0.01)."""
    b = math.asin(E.EARTH_RADIUS / R_LEO)
    theta = np.arange(math.pi / 2, math.pi / 2 + b + 0.1, 1e-5)  # from the terminator into the shadow
    nu = E.shadow_conical(_ring(theta), SUN)
    assert np.all((nu >= 0.0) & (nu <= 1.0))
    assert np.all(np.diff(nu) <= 1e-12)
    assert np.max(np.abs(np.diff(nu))) < 0.01
    assert nu[0] == 1.0 and nu[-1] == 0.0
    partial = (nu > 0) & (nu < 1)
    assert 100 < partial.sum() < 10_000


def test_penumbra_spans_the_suns_apparent_diameter_in_separation():
    """In the separation c, lit is c >= a + b and umbra c <= b - a: the partial phase covers exactly
    c in (b - a, a + b), a width 2a = 2 asin(R_sun / |r_sun - r|) ~ 0.533 deg (sampling 1e-6 rad)."""
    b0 = math.asin(E.EARTH_RADIUS / R_LEO)
    theta = np.arange(math.pi - b0 - 0.02, math.pi - b0 + 0.02, 1e-6)       # around the shadow entry
    r = _ring(theta)
    a, b, c = E.apparent_geometry(r, SUN)
    nu = E.shadow_conical(r, SUN)
    partial = (nu > 0) & (nu < 1)
    assert np.all(c[partial] > b[partial] - a[partial]) and np.all(c[partial] < a[partial] + b[partial])
    width = c[partial].max() - c[partial].min()
    assert width == pytest.approx(2 * a[partial].mean(), abs=2e-6)
    assert math.degrees(2 * a.mean()) == pytest.approx(2 * math.degrees(math.asin(SUN_RADIUS / AU)), abs=1e-4)


def test_sun_centred_on_the_limb_is_half_lit():
    """c = b: half the solar disk behind an edge whose curvature is ~a/b = 0.004 of the disk: 0.5 +- 0.01."""
    a, b = math.asin(SUN_RADIUS / AU), math.asin(E.EARTH_RADIUS / R_LEO)
    assert float(E.occulted_fraction(a, b, b)) == pytest.approx(0.5, abs=0.01)


def test_annular_beyond_the_umbra_apex():
    """At 2e9 m on the anti-Sun line the Earth (b = 3.2 mrad) looks smaller than the Sun (a = 4.7 mrad):
    nu = 1 - b^2 / a^2 exactly (both disks concentric)."""
    r = np.array([-2e9, 0.0, 0.0])
    a, b, c = E.apparent_geometry(r, SUN)
    assert b < a and c == 0.0
    assert float(E.shadow_conical(r, SUN)) == pytest.approx(1 - b * b / (a * a), rel=1e-12)
    assert float(E.shadow_cylindrical(r, SUN)) == 0.0


def test_eclipse_fraction_of_an_orbit_with_the_sun_in_its_plane():
    """Cylindrical: the shadowed arc is 2 asin(R_E / r), so the fraction is asin(R_E / r) / pi = 0.3778
    at 500 km (to the 1e-5 sampling); the conical umbra is a little shorter and umbra + half the
    penumbra matches it to 1e-3 (the cone's convergence over 7000 km against 1.4e6 km)."""
    theta = np.linspace(0, 2 * math.pi, 200_001)[:-1]
    r = _ring(theta)
    expected = math.asin(E.EARTH_RADIUS / R_LEO) / math.pi
    cyl = E.shadow_cylindrical(r, SUN)
    assert np.mean(cyl == 0.0) == pytest.approx(expected, abs=1e-4)
    con = E.shadow_conical(r, SUN)
    assert np.mean(1.0 - con) == pytest.approx(expected, abs=1e-3)
    assert np.all(cyl[con == 0.0] == 0.0)                               # umbra inside the cylinder


def test_batch_broadcasts_positions_against_one_sun():
    r = np.stack([_ring(np.linspace(0, 6, 7)), _ring(np.linspace(1, 7, 7))])   # (2, 7, 3)
    nu = E.shadow_conical(r, SUN)
    assert nu.shape == (2, 7)
    np.testing.assert_array_equal(nu[1, 3], E.shadow_conical(r[1, 3], SUN))


@settings(derandomize=True, max_examples=200, deadline=None)
@given(r=st.lists(st.floats(-5e8, 5e8), min_size=3, max_size=3), s=st.lists(st.floats(-1, 1), min_size=3, max_size=3))
def test_any_geometry_gives_a_fraction_in_unit_interval(r, s):
    """Random satellite positions (inside the Earth, at the centre's side, far away) and Sun directions:
    both models return a number in [0, 1], never NaN; conical umbra implies cylindrical shadow near the
    Earth (r < 1e6 km: the umbra cone is inside the cylinder there)."""
    r = np.array(r)
    s = np.array(s)
    if np.linalg.norm(s) < 1e-3 or np.linalg.norm(r) < 1.0:
        return
    sun = AU * s / np.linalg.norm(s)
    con, cyl = float(E.shadow_conical(r, sun)), float(E.shadow_cylindrical(r, sun))
    assert 0.0 <= con <= 1.0 and cyl in (0.0, 1.0)
    if con == 0.0 and np.linalg.norm(r) > E.EARTH_RADIUS:
        assert cyl == 0.0
