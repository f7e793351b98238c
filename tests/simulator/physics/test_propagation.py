"""Radio propagation: Friis, two-ray ground reflection, Fresnel coefficients, antenna patterns, fading."""
from __future__ import annotations

import numpy as np
import pytest

from simulator.physics import propagation as prop
from simulator.seeding import rng_for

# NumPy >= 2.0 names it trapezoid, 1.24-1.26 (allowed by pyproject) trapz: the same rule
_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # noqa: NPY201 (numpy < 2 has only trapz)

F = 2.44e9


def test_friis_by_hand_and_six_db_per_doubling():
    # 20 log10(4 pi 1e4 2.44e9 / 299792458) = 120.196 dB
    assert float(prop.free_space_path_loss_db(10e3, F)) == pytest.approx(120.196, abs=0.001)
    loss = prop.free_space_path_loss_db(np.array([100.0, 200.0, 400.0]), F)
    assert np.allclose(np.diff(loss), 20 * np.log10(2.0))
    with pytest.raises(ValueError, match="range_m"):
        prop.free_space_path_loss_db(-1.0, F)


def test_two_ray_at_10_km_matches_plane_earth_law():
    # heights 30 m (drone) and 1.5 m (receiver): 40 log10(1e4) - 20 log10(45) = 126.94 dB vs Friis 120.20 dB
    two_ray = float(prop.two_ray_path_loss_db(10e3, 30.0, 1.5, F, reflection=-1.0)[0])
    assert two_ray == pytest.approx(160.0 - 20 * np.log10(45.0), abs=0.1)
    assert two_ray - float(prop.free_space_path_loss_db(10e3, F)) == pytest.approx(6.8, abs=0.1)
    # a real (lossy, vertically polarised) ground is within a fraction of a dB at this grazing angle
    lossy = float(prop.two_ray_path_loss_db(10e3, 30.0, 1.5, F, reflection="vertical")[0])
    assert abs(lossy - two_ray) < 0.5


def test_two_ray_exceeds_free_space_beyond_about_1p5_km_at_low_heights():
    # Gamma = -1: |1 - exp(-j k D)| < 1 once the path difference D = 2 ht hr / d < lambda / 6,
    # i.e. beyond d = 12 ht hr / lambda = 1.46 km for ht = 10 m, hr = 1.5 m
    lam = prop.SPEED_OF_LIGHT_MPS / F
    crossover = 12 * 10.0 * 1.5 / lam
    assert crossover == pytest.approx(1465.0, abs=5.0)
    d = np.array([0.8, 0.95, 1.05, 1.5, 3.0, 10.0]) * crossover
    excess = prop.two_ray_path_loss_db(d, 10.0, 1.5, F) - prop.free_space_path_loss_db(d, F)
    assert np.all(excess[:2] < 0) and np.all(excess[2:] > 0)
    assert np.all(np.diff(excess[2:]) > 0)                       # 40 dB/decade vs 20 dB/decade


def test_fresnel_coefficient_limits():
    psi = np.radians([0.01, 1.0, 10.0, 45.0, 89.9])
    for pol in ("vertical", "horizontal"):
        g = prop.ground_reflection_coefficient(psi, F, polarization=pol)
        assert np.all(np.abs(g) <= 1.0)
        assert g[0] == pytest.approx(-1.0, abs=0.01)              # grazing incidence
    gv = prop.ground_reflection_coefficient(psi, F, polarization="vertical")
    assert np.min(np.abs(gv)) < 0.5                               # the Brewster dip of vertical polarisation
    # normal incidence, lossless ground eps 4: |Gamma| = (2 - 1) / (2 + 1)
    g_normal = prop.ground_reflection_coefficient(np.pi / 2, F, polarization="horizontal",
                                                  relative_permittivity=4.0, conductivity_s_per_m=0.0)
    assert abs(g_normal) == pytest.approx(1 / 3, abs=1e-9)
    with pytest.raises(ValueError, match="polarization"):
        prop.ground_reflection_coefficient(psi, F, polarization="circular")


def _sphere_average(kind: str) -> float:
    theta = np.linspace(0.0, np.pi, 2001)
    phi = np.linspace(0.0, 2 * np.pi, 65)[:-1]
    t, p = np.meshgrid(theta, phi, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    g = prop.antenna_gain(kind, d, np.array([0.0, 0.0, 1.0]))
    return float(_trapezoid(np.mean(g, axis=1) * np.sin(theta), theta) / 2)


def test_antenna_patterns():
    z = np.array([0.0, 0.0, 1.0])
    broadside = prop.antenna_gain("dipole", np.array([1.0, 0.0, 0.0]), z)
    assert 10 * np.log10(broadside) == pytest.approx(2.15, abs=0.01)
    assert prop.antenna_gain("dipole", np.array([0.0, 0.0, 1.0]), z) < 1e-6    # null along the element
    assert _sphere_average("dipole") == pytest.approx(1.0, abs=0.005)          # radiated power conserved
    assert 10 * np.log10(prop.antenna_gain("patch", z, z)) == pytest.approx(7.78, abs=0.01)
    back = prop.antenna_gain("patch", -z, z) / prop.antenna_gain("patch", z, z)
    assert 10 * np.log10(back) == pytest.approx(-20.0)
    assert _sphere_average("patch") == pytest.approx(1.0, abs=0.05)           # front lobe 1 + back lobe 3 %
    assert prop.antenna_gain("isotropic", np.array([0.3, 0.2, 0.1]), z) == 1.0
    with pytest.raises(ValueError, match="antenna"):
        prop.antenna_gain("yagi", z, z)


@pytest.mark.parametrize("k_db", [3.0, 10.0])
def test_rician_k_factor_recovered_from_samples(k_db):
    h = prop.rician_gains(rng_for(1, "rf", 500), 200_000, k_db)
    assert np.mean(np.abs(h) ** 2) == pytest.approx(1.0, abs=0.01)
    k = prop.rician_k_from_samples(h)
    assert 10 * np.log10(k) == pytest.approx(k_db, abs=0.3)


def test_rayleigh_envelope_is_exponential_power():
    h = prop.rician_gains(rng_for(2, "rf", 501), 200_000, None)
    p = np.abs(h) ** 2
    assert np.mean(p) == pytest.approx(1.0, abs=0.01)
    assert np.var(p) == pytest.approx(1.0, abs=0.03)               # exponential: variance = mean^2
    assert np.mean(p < 0.1) == pytest.approx(1 - np.exp(-0.1), abs=0.005)   # 10 dB fades 9.5 % of the time
    assert prop.rician_k_from_samples(h) < 0.1
    a = prop.rician_gains(rng_for(3, "rf", 1), 100, 6.0)
    b = prop.rician_gains(rng_for(3, "rf", 1), 100, 6.0)
    assert a.tobytes() == b.tobytes()
