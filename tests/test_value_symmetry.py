"""Group-averaged V̂: exact invariance, exact gradient, mirror-image encounters get
mirror-image controls, the policy accepts the setting."""

import pytest
import torch

from madpinn.value_functions.symmetry import GROUPS, observation_transforms, symmetrize
from policy_models import tiny_models
from settings_helpers import observation_settings

SPEC = observation_settings()


def random_obs(vhat, B=64, seed=0):
    g = torch.Generator().manual_seed(seed)
    hw = vhat.system.half_widths().to(torch.float64)
    obs = (2 * torch.rand(B, SPEC.dim, generator=g, dtype=torch.float64) - 1) * hw * 0.5
    z = torch.rand(B, generator=g, dtype=torch.float64) * 0.3 * vhat.z_max
    return obs, z


@pytest.mark.parametrize("group,size", [("none", 1), ("point", 2), ("d4", 8), ("full", 16)])
def test_transforms_are_orthogonal_group_elements(group, size):
    g = observation_transforms(group, 2, SPEC.layout)
    assert g.shape == (size, SPEC.dim, SPEC.dim)
    eye = torch.eye(SPEC.dim, dtype=torch.float64)
    assert torch.allclose(g @ g.transpose(1, 2), eye.expand_as(g))
    # closed under composition: every product is again an element
    flat = g.reshape(size, -1)
    for a in g:
        for b in g:
            assert bool(((flat - (a @ b).reshape(1, -1)).abs().amax(1) < 1e-12).any())


@pytest.mark.parametrize("group", ["point", "d4", "full"])
def test_averaged_value_is_invariant_and_its_gradient_exact(group):
    vhat, _ = tiny_models(torch.float64)
    sym = symmetrize(vhat, group)
    obs, z = random_obs(vhat)
    v, grad, dz = sym.value_and_grad(obs, z, 0.0)
    assert torch.allclose(v, sym.value(obs, z, 0.0), atol=1e-12)
    for m in observation_transforms(group, 2, SPEC.layout):
        assert torch.allclose(sym.value(obs @ m.T, z, 0.0), v, atol=1e-10)
    for col in (0, 3, 7):
        e = torch.zeros_like(obs)
        e[:, col] = 1e-6
        fd = (sym.value(obs + e, z, 0.0) - sym.value(obs - e, z, 0.0)) / 2e-6
        assert torch.allclose(fd, grad[:, col], atol=1e-5)
    fdz = (sym.value(obs, z + 1e-6, 0.0) - sym.value(obs, z - 1e-6, 0.0)) / 2e-6
    assert torch.allclose(fdz, dz, atol=1e-5)
    # the plain network is not invariant, so the test can fail
    assert not torch.allclose(vhat.value(-obs, z, 0.0), vhat.value(obs, z, 0.0), atol=1e-6)


def test_mirror_image_encounters_get_mirror_image_controls():
    """Two agents in an encounter related by the 180° rotation (o → −o) swerve oppositely."""
    vhat, _ = tiny_models(torch.float64)
    obs, z = random_obs(vhat, seed=3)
    for group in ("point", "d4"):
        sym = symmetrize(vhat, group)
        _, g1, _ = sym.value_and_grad(obs, z, 0.0)
        _, g2, _ = sym.value_and_grad(-obs, z, 0.0)
        u1, u2 = sym.system.optimal_control(g1)[:, 0], sym.system.optimal_control(g2)[:, 0]
        assert torch.equal(u1, -u2)
    assert symmetrize(vhat, "none") is vhat
    with pytest.raises(ValueError, match="symmetry group"):
        symmetrize(vhat, "c3")
    assert set(GROUPS) == {"none", "point", "d4", "full"}
