"""V_s clamped into its exact band [free-drift bound, ψ] (issue 37): inside the band, equal to the
network where the network is inside, the active bound's gradient where it is not, and the
free-drift bound itself correct against brute force."""

import torch

from conftest import REPO
from madpinn.value_functions import load_vs

VS = REPO / "models" / "vs.pt"


def _states(n=4000, seed=0):
    vs = load_vs(VS, dtype=torch.float64)
    return vs, vs.system.sample(n, torch.Generator().manual_seed(seed), dtype=torch.float64)


def test_free_drift_bound_is_the_closest_approach_without_control():
    vs, x = _states(500)
    lo, _ = vs.system.free_drift_and_grad(x, 0.7)
    taus = torch.linspace(0.0, 0.7, 7001, dtype=torch.float64)
    brute = (x[:, None, 0:2] + x[:, None, 2:4] * taus[None, :, None]).norm(dim=-1).min(1).values - vs.collision_radius
    assert float((lo - brute).abs().max()) < 1e-6 + 0.7 / 7000 * 16     # grid step × largest speed
    assert bool((lo <= vs.system.target(x) + 1e-12).all())


def test_banded_value_lies_in_the_band_and_equals_the_network_inside_it():
    vs, x = _states()
    raw = vs.value(x, 0.0)
    banded = load_vs(VS, dtype=torch.float64, band=True)
    v = banded.value(x, 0.0)
    lo, _ = vs.system.free_drift_and_grad(x, vs.horizon)
    hi = vs.system.target(x)
    assert bool(((v >= lo - 1e-12) & (v <= hi + 1e-12)).all())
    inside = (raw >= lo) & (raw <= hi)
    assert 0.1 < float(inside.double().mean()) < 0.9                       # both cases are exercised
    assert torch.equal(v[inside], raw[inside])
    assert not vs.band and banded.band


def test_banded_gradient_matches_finite_differences():
    vs = load_vs(VS, dtype=torch.float64, band=True)
    _, x = _states(300, seed=1)
    v, g = vs.value_and_grad(x, 0.0)
    assert torch.allclose(v, vs.value(x, 0.0), atol=1e-9)
    eps, eye = 1e-5, torch.eye(4, dtype=torch.float64)
    fd = torch.stack([(vs.value(x + eps * eye[k], 0.0) - vs.value(x - eps * eye[k], 0.0)) / (2 * eps) for k in range(4)], -1)
    err = (fd - g).abs().max(-1).values
    assert float(err.quantile(0.95)) < 1e-4                                 # kinks of the clamp excepted
