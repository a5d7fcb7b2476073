"""The strain a ball leaves in a layer, from the axisymmetric field (``fem.layer_strain``):
Hertz's field where the layer is deep, an independent audit's converged means, mesh
convergence, where the largest mean lies (the foam's surface on the axis, a thin layer's
base), pointwise strains, the table against fresh fields, the disk cache, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import fem
import fem.layer_strain as layer_strain
from fem import FemError, LayerBallStrain, axisymmetric_layer_field
from fem.layer_strain import largest_ball_mean

# quadruped-foam's foam and ANYmal's ball.
THICKNESS, POISSON, YOUNG, BALL, RADIUS = 0.05, 0.4, 3e6, 0.031, 0.02


def _hertz_axis(depth_share, poisson):
    """Hertz's strains on the axis per (N / Pa) times a^2, at depth z = share a (Johnson, eq. 3.45)."""
    peak = 3.0 / (2.0 * np.pi)
    vertical = -peak / (1.0 + depth_share**2)
    radial = peak * (-(1.0 + poisson) * (1.0 - depth_share * np.arctan(1.0 / depth_share))
                     + 0.5 / (1.0 + depth_share**2))
    return (1.0 - poisson) * radial - poisson * vertical, vertical - 2.0 * poisson * radial


@pytest.mark.parametrize("poisson", [0.4, 0.49])
def test_a_deep_layers_field_is_hertzs_under_the_ball(poisson):
    # Forty contact radii deep the base is far: on the axis the strains are Hertz's half-space
    # ones (selective integration keeps nu = 0.49 from locking: 2-3 % stiff without it).
    a = 0.005
    field = axisymmetric_layer_field(a, 40 * a, poisson, 0.0)
    for share in (0.5, 1.0):
        radial, vertical = _hertz_axis(share, poisson)
        mean = field.ball_means(0.02 * a, [[0.0, share * a]])[0] * a * a
        np.testing.assert_allclose([mean[0, 0], mean[1, 1], mean[2, 2]], [radial, radial, vertical], rtol=0.011)
        assert abs(mean[0, 2]) < 1e-9 * abs(vertical)


@pytest.mark.parametrize(("depth", "audit"), [(2.5514e-3, 0.0262), (1.6505e-3, 0.0134)])
def test_the_largest_20_mm_mean_is_the_independent_audits(depth, audit):
    # The audit (bench/results/audit-layer-balls-2026-12-04.md) ball-averaged its own 3D FEM's
    # field, binned to 1 mm voxels, at two planned balls: 2.62 % and 1.34 % (this: 2.60 and
    # 1.33 %; the voxels and the audit's 3D mesh, whose forces ran 2 % high, allow 1.5 %).
    force, contact = fem.sphere_on_layer_force(depth, BALL, THICKNESS, YOUNG, POISSON)
    field = axisymmetric_layer_field(contact, THICKNESS, POISSON, RADIUS)
    strain = force * largest_ball_mean(field, RADIUS, contact) / YOUNG
    assert strain == pytest.approx(audit, rel=0.015)


def test_the_largest_mean_converges_as_the_elements_halve(monkeypatch):
    contact = 0.0093
    coarse = largest_ball_mean(axisymmetric_layer_field(contact, THICKNESS, POISSON, RADIUS), RADIUS, contact)
    monkeypatch.setattr(layer_strain, "_CONTACT_CELLS", 2 * layer_strain._CONTACT_CELLS)
    monkeypatch.setattr(layer_strain, "_AVERAGING_CELLS", 2 * layer_strain._AVERAGING_CELLS)
    monkeypatch.setattr(layer_strain, "_GROWTH", 1.07)
    fine = largest_ball_mean(axisymmetric_layer_field(contact, THICKNESS, POISSON, RADIUS), RADIUS, contact)
    assert coarse == pytest.approx(fine, rel=2e-3)


def test_the_search_finds_the_largest_mean_where_a_thin_layers_base_holds_it():
    # A 10 mm layer under a 20 mm mean: the largest lies at the base, off the axis (an
    # axis-only search was 4 % low at nu = 0.4); the search matches a fine grid of centres.
    contact, thickness = 0.003, 0.01
    field = axisymmetric_layer_field(contact, thickness, POISSON, RADIUS)
    centres = [[x, z] for x in np.linspace(0.0, contact + RADIUS, 24) for z in np.linspace(0.0, thickness, 21)]
    eigenvalues = np.linalg.eigvalsh(field.ball_means(RADIUS, centres))
    grid = np.max(np.maximum(eigenvalues[:, -1], -eigenvalues[:, 0]))
    found = largest_ball_mean(field, RADIUS, contact)
    assert grid * (1.0 - 1e-3) <= found
    on_axis_surface = np.max(np.abs(np.linalg.eigvalsh(field.ball_means(RADIUS, [[0.0, 0.0]])[0])))
    assert found > 1.02 * on_axis_surface


def test_a_strain_radius_of_zero_takes_the_largest_pointwise_strain_hertzs_below_the_surface():
    # Hertz's largest strain on the axis is the vertical one, about half a contact radius
    # deep (2.2 times the surface's at nu = 0.4).
    a = 0.005
    field = axisymmetric_layer_field(a, 40 * a, POISSON, 0.0)
    shares = np.linspace(0.01, 3.0, 3000)
    hertz = np.max(np.abs([_hertz_axis(share, POISSON)[1] for share in shares])) / a**2
    assert largest_ball_mean(field, 0.0, a) == pytest.approx(hertz, rel=0.015)
    # A ball far smaller than the contact: its cells stop at a / 48, and its mean is the
    # pointwise largest's.
    small = axisymmetric_layer_field(a, 40 * a, POISSON, 1e-4)
    assert small.displacement.size < 2e5
    assert largest_ball_mean(small, 1e-4, a) == pytest.approx(hertz, rel=0.015)


def test_on_the_foam_the_largest_mean_is_centred_on_the_axis_at_the_surface():
    contact = 0.0093
    field = axisymmetric_layer_field(contact, THICKNESS, POISSON, RADIUS)
    centres = [[x, z] for x in (0.0, 0.002, 0.005, 0.01, 0.02) for z in (0.0, 0.002, 0.005, 0.01)]
    eigenvalues = np.linalg.eigvalsh(field.ball_means(RADIUS, centres))
    magnitudes = np.maximum(eigenvalues[:, -1], -eigenvalues[:, 0])
    assert int(np.argmax(magnitudes)) == 0
    assert largest_ball_mean(field, RADIUS, contact) == pytest.approx(magnitudes[0], rel=1e-12)
    # Off the axis the mean has a shear; on it, none, and x and y stretch alike.
    on_axis, off_axis = field.ball_means(RADIUS, [[0.0, 0.0], [0.01, 0.0]])
    assert abs(on_axis[0, 2]) < 1e-12 * abs(on_axis[2, 2]) < abs(off_axis[0, 2])
    assert on_axis[0, 0] == pytest.approx(on_axis[1, 1], rel=1e-12)


def test_the_table_agrees_with_fresh_fields_and_its_slope_with_differences():
    law = fem.BallOnLayer(BALL, THICKNESS, YOUNG, POISSON)
    widest = law.contact_radius(law.force_limit)
    table = LayerBallStrain(THICKNESS, POISSON, RADIUS, 0.05 * widest, widest)
    for a in (0.07 * widest, 0.3 * widest, 0.55 * widest, 0.93 * widest):
        fresh = largest_ball_mean(axisymmetric_layer_field(a, THICKNESS, POISSON, RADIUS), RADIUS, a)
        value, slope = table.per_force(a)
        assert value == pytest.approx(fresh, rel=1e-3)
        step = 1e-7
        assert slope == pytest.approx((table.per_force(a + step)[0] - table.per_force(a - step)[0]) / (2 * step),
                                      rel=1e-5)
    # Held beyond its ends, with no slope there.
    assert table.per_force(0.0) == (table.per_force(0.05 * widest)[0], 0.0)
    assert table.per_force(2 * widest) == (table.per_force(widest)[0], 0.0)
    # A wider contact spreads the same force: less strain.
    assert table.per_force(widest)[0] < table.per_force(0.5 * widest)[0] < table.per_force(0.05 * widest)[0]


def test_bad_input_is_refused_with_what_is_wrong():
    with pytest.raises(FemError, match=r"contact_radius must be finite and > 0, got -0.001"):
        axisymmetric_layer_field(-0.001, THICKNESS, POISSON, RADIUS)
    with pytest.raises(FemError, match=r"poisson_ratio must lie in \[0, 0.5\), got 0.5"):
        axisymmetric_layer_field(0.005, THICKNESS, 0.5, RADIUS)
    with pytest.raises(FemError, match=r"averaging_radius must be finite and >= 0, got nan"):
        axisymmetric_layer_field(0.005, THICKNESS, POISSON, float("nan"))
    with pytest.raises(FemError, match=r"the contact radii must satisfy 0 < smallest <= largest, got 0.01 and 0.005"):
        LayerBallStrain(THICKNESS, POISSON, RADIUS, 0.01, 0.005)


def test_a_table_read_back_from_the_disk_cache_is_the_computed_one(tmp_path, monkeypatch):
    monkeypatch.setenv("SOFTCBM_CACHE_DIR", str(tmp_path))
    made = LayerBallStrain(THICKNESS, POISSON, RADIUS, 0.002, 0.02)
    assert list(tmp_path.rglob("largest-means.entry"))
    read = LayerBallStrain(THICKNESS, POISSON, RADIUS, 0.002, 0.02)
    monkeypatch.setenv("SOFTCBM_CACHE", "off")
    fresh = LayerBallStrain(THICKNESS, POISSON, RADIUS, 0.002, 0.02)
    for a in (0.002, 0.0071, 0.02):
        assert made.per_force(a) == read.per_force(a) == fresh.per_force(a)
