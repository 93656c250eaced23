"""Tests for lasmp.modules: the composed LAS-MP actor, its estimators, ROA losses and export."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from rsl_rl.utils import resolve_callable
from tensordict import TensorDict

from lasmp.modules import HistoryEstimator, ImplicitEncoder, LasmpActor
from lasmp.modules.export import write_onnx
from lasmp.modules.obs_groups import (
    GROUP_EXPLICIT,
    GROUP_IMPLICIT,
    X_EXP_NAMES,
    omega_plf_z,
    v_body_xy,
    v_plf_xy,
)

N, H, D = 6, 20, 44
GROUPS = {"actor": ["policy", "history", "priv_explicit", "priv_implicit", "alignment"], "critic": ["critic"]}
DIST = {"class_name": "GaussianDistribution", "init_std": 1.0, "std_type": "scalar", "learn_std": True}

ABLATIONS = {
    "lasmp": ({}, 76),
    "no_alignment_command": ({"use_alignment": False}, 73),
    "no_platform_velocity_estimates": ({"explicit": "no_platform", "use_alignment": False}, 67),
    "no_explicit_estimator": ({"explicit": "none", "use_alignment": False}, 60),
    "no_explicit_estimator_history": (
        {"explicit": "none", "use_alignment": False, "history_input": True},
        940,
    ),
}


def make_obs(n: int = N, seed: int = 0) -> TensorDict:
    g = torch.Generator().manual_seed(seed)
    return TensorDict(
        {
            "policy": torch.randn(n, D, generator=g),
            "history": torch.randn(n, H, D, generator=g),
            "priv_explicit": torch.randn(n, 13, generator=g),
            "priv_implicit": 3.0 + 10.0 * torch.randn(n, 29, generator=g),
            "alignment": torch.randn(n, 3, generator=g),
            "critic": torch.randn(n, 95, generator=g),
        },
        batch_size=[n],
    )


def make_actor(seed: int = 0, normalize_stats: bool = True, **kw) -> LasmpActor:
    torch.manual_seed(seed)
    actor = LasmpActor(make_obs(), GROUPS, "actor", 12, distribution_cfg=DIST, **kw)
    if normalize_stats and actor.obs_normalization:
        # non-trivial statistics so normalization mistakes show up
        stats = make_obs(n=256, seed=99)
        stats["policy"] = 2.0 * stats["policy"] + 0.5
        actor.update_normalization(stats)
    return actor


def with_nan_privileged(obs: TensorDict) -> TensorDict:
    obs = obs.clone()
    for k in ("priv_explicit", "priv_implicit", "alignment"):
        obs[k] = torch.full_like(obs[k], float("nan"))
    return obs


def test_submodules_shapes():
    enc = ImplicitEncoder(29, 16)
    assert enc(torch.randn(4, 29)).shape == (4, 16)
    assert sum(isinstance(m, torch.nn.Linear) for m in enc.modules()) == 2
    est = HistoryEstimator(44, 20, 13, 32, 32)
    assert est(torch.randn(4, 20, 44)).shape == (4, 13)
    assert sum(isinstance(m, torch.nn.Conv1d) for m in est.modules()) == 2
    with pytest.raises(ValueError):
        HistoryEstimator(44, 4, 13)


@pytest.mark.parametrize("autocast", [False, True])
def test_estimator_is_its_layers_in_sequence_to_the_bit(autocast):
    """The estimator hands its convolutions a contiguous copy of the transposed per-step features (oneDNN
    is faster on it): the output and every gradient are those of the layers applied to the plain view."""
    torch.manual_seed(0)
    est = HistoryEstimator(obs_dim=44, history_len=20, out_dim=13)
    history = torch.randn(64, 20, 44)

    def run(forward):
        est.zero_grad()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=autocast):
            out = forward(history)
        out.float().square().sum().backward()
        return [out.detach().float()] + [p.grad.clone() for p in est.parameters()]

    def layers(h):  # the view itself, as the convolutions took it before
        return est.head(est.cnn(est.step_mlp(h).transpose(1, 2)).flatten(1))

    for got, want in zip(run(est), run(layers), strict=True):
        assert torch.equal(got, want)


@pytest.mark.parametrize("name", list(ABLATIONS))
def test_backbone_input_dim_and_shapes(name):
    kw, dim = ABLATIONS[name]
    actor = make_actor(**kw)
    assert actor.backbone_input_dim == dim
    assert actor.mlp[0].in_features == dim
    linears = [m for m in actor.mlp if isinstance(m, torch.nn.Linear)]
    assert [m.out_features for m in linears] == [512, 256, 128, 12]
    obs = make_obs(seed=1)
    assert actor.get_latent(obs).shape == (N, dim)
    assert actor(obs).shape == (N, 12)
    actor.deploy = True
    assert actor.get_latent(obs).shape == (N, dim)
    assert actor(obs).shape == (N, 12)
    n_exp = {"all": 13, "no_platform": 7, "none": 0}[kw.get("explicit", "all")]
    if n_exp:
        assert actor.explicit_estimator.out_dim == n_exp
    else:
        assert actor.explicit_estimator is None
    assert actor.implicit_estimator.out_dim == 16


def test_invalid_arguments():
    with pytest.raises(ValueError, match="explicit"):
        make_actor(explicit="platform_only", use_alignment=False)
    with pytest.raises(ValueError, match="use_alignment"):
        make_actor(explicit="no_platform")
    with pytest.raises(ValueError, match="history"):
        LasmpActor(
            make_obs(), {"actor": ["policy", "priv_explicit", "priv_implicit", "alignment"]}, "actor", 12
        )


def test_class_name_resolves():
    assert resolve_callable("lasmp.modules.policy:LasmpActor") is LasmpActor


@pytest.mark.parametrize("name", list(ABLATIONS))
def test_deploy_uses_no_privileged_groups(name):
    actor = make_actor(**ABLATIONS[name][0])
    obs = make_obs(seed=2)
    actor.deploy = True
    ref = actor(obs)
    out = actor(with_nan_privileged(obs))
    assert torch.isfinite(out).all()
    torch.testing.assert_close(out, ref)
    # ...but does use the history
    obs2 = obs.clone()
    obs2["history"] = obs2["history"] + 1.0
    assert not torch.allclose(actor(obs2), ref)
    # training mode reads the privileged groups
    actor.deploy = False
    assert not torch.isfinite(actor(with_nan_privileged(obs))).all()


def test_training_mode_uses_privileged_inputs():
    actor = make_actor()
    obs = make_obs(seed=3)
    ref = actor(obs)
    for key in ("priv_explicit", "priv_implicit", "alignment"):
        changed = obs.clone()
        changed[key] = changed[key] + 1.0
        assert not torch.allclose(actor(changed), ref), key
    # the history does not enter the backbone in training mode without history_input
    changed = obs.clone()
    changed["history"] = changed["history"] + 1.0
    torch.testing.assert_close(actor(changed), ref)


def test_alignment_hat_formula(monkeypatch):
    actor = make_actor(obs_normalization=False)
    obs = make_obs(seed=4)
    x_hat = torch.randn(N, 13)
    monkeypatch.setattr(actor.explicit_estimator, "forward", lambda h: x_hat)
    actor.deploy = True
    latent = actor.get_latent(obs)
    o = obs["policy"]
    expected = torch.stack(
        [x_hat[:, 7] - x_hat[:, 4], x_hat[:, 8] - x_hat[:, 5], x_hat[:, 12] - o[:, 5]], dim=-1
    )
    torch.testing.assert_close(latent[:, :D], o)
    torch.testing.assert_close(latent[:, D : D + 13], x_hat)
    torch.testing.assert_close(latent[:, D + 13 : D + 16], expected)


def test_named_x_exp_columns_are_the_named_dims():
    x_exp = torch.arange(len(X_EXP_NAMES)).unsqueeze(0)  # column i holds i

    def names(columns: torch.Tensor) -> list[str]:
        return [X_EXP_NAMES[i] for i in columns[0].tolist()]

    assert names(v_body_xy(x_exp)) == ["v_body_x", "v_body_y"]
    assert names(v_plf_xy(x_exp)) == ["v_plf_x", "v_plf_y"]
    assert names(omega_plf_z(x_exp)) == ["omega_plf_z"]


def test_history_normalized_with_obs_statistics():
    actor = make_actor(explicit="none", use_alignment=False, history_input=True)
    norm = actor.obs_normalizer
    assert norm.count > 0
    obs = make_obs(seed=5)
    hist_n = actor.normalize_history(obs["history"])
    manual = (obs["history"] - norm.mean[:D]) / (norm.std[:D] + norm.eps)
    torch.testing.assert_close(hist_n, manual)
    torch.testing.assert_close(actor.get_latent(obs)[:, -H * D :], manual.flatten(1))
    # the encoder normalizer was updated as well
    assert actor.encoder.normalizer.count == 256


def _grads(params) -> list[torch.Tensor | None]:
    return [p.grad for p in params]


def _nonzero(grads) -> bool:
    return any(g is not None and g.abs().sum() > 0 for g in grads)


def _zero(grads) -> bool:
    return all(g is None or g.abs().sum() == 0 for g in grads)


@pytest.mark.parametrize("loss_name", ["exp", "imp_est", "imp_reg"])
def test_roa_stop_gradients(loss_name):
    actor = make_actor()
    losses, _ = actor.roa_losses(make_obs(seed=6), lam=0.2)
    assert set(losses) == {"exp", "imp_est", "imp_reg"}
    actor.zero_grad(set_to_none=True)
    losses[loss_name].backward()
    enc = _grads(actor.encoder_parameters())
    imp = _grads(actor.implicit_estimator.parameters())
    exp = _grads(actor.explicit_estimator.parameters())
    backbone = _grads(actor.mlp.parameters())
    assert _zero(backbone)
    if loss_name == "exp":
        assert _nonzero(exp) and _zero(imp) and _zero(enc)
    elif loss_name == "imp_est":
        assert _nonzero(imp) and _zero(enc) and _zero(exp)
    else:
        assert _nonzero(enc) and _zero(imp) and _zero(exp)


def test_roa_loss_values():
    actor = make_actor()
    obs = make_obs(seed=7)
    with torch.no_grad():
        l_imp = actor.encoder(obs["priv_implicit"])
        l_hat = actor.implicit_estimator(actor.normalize_history(obs["history"]))
        losses, _ = actor.roa_losses(obs, lam=0.5)
        ref = (l_hat - l_imp).square().sum(-1).mean()
    torch.testing.assert_close(losses["imp_est"], ref)
    torch.testing.assert_close(losses["imp_reg"], 0.5 * ref)
    assert len(actor.estimator_parameters()) == len(list(actor.implicit_estimator.parameters())) * 2


def test_estimation_errors():
    actor = make_actor()
    obs = make_obs(seed=8)
    _, errs = actor.roa_losses(obs, lam=0.5)
    for name in X_EXP_NAMES + ("l_imp_l2",):
        assert name in errs and np.isfinite(float(errs[name])) and float(errs[name]) > 0
    x_hat, l_hat = actor.estimates(obs)
    by_hand = (x_hat - obs[GROUP_EXPLICIT][:, : actor.num_explicit]).abs().mean(0)
    torch.testing.assert_close(torch.stack([errs[n] for n in X_EXP_NAMES]), by_hand)
    torch.testing.assert_close(
        errs["l_imp_l2"], (l_hat - actor.encoder(obs[GROUP_IMPLICIT])).norm(dim=-1).mean()
    )
    _, small = make_actor(explicit="no_platform", use_alignment=False).roa_losses(make_obs(), lam=0.5)
    assert "v_body_z" in small and "v_plf_x" not in small


def test_ppo_style_calls():
    actor = make_actor()
    obs = make_obs(seed=9)
    actions = actor(obs, stochastic_output=True)
    assert actions.shape == (N, 12)
    logp = actor.get_output_log_prob(actions)
    assert logp.shape == (N,) and torch.isfinite(logp).all()
    assert actor.output_entropy.shape == (N,)
    mean, std = actor.output_distribution_params
    torch.testing.assert_close(mean, actor(obs))
    (-logp.mean()).backward()
    assert actor.distribution.std_param.grad is not None
    assert _nonzero(_grads(actor.encoder_parameters()))  # PPO trains the encoder through the backbone
    assert _zero(_grads(actor.estimator_parameters()))  # but not the estimators


@pytest.mark.parametrize("name", ["lasmp", "no_platform_velocity_estimates", "no_explicit_estimator_history"])
def test_onnx_export_matches_deploy(tmp_path, name):
    ort = pytest.importorskip("onnxruntime")
    actor = make_actor(**ABLATIONS[name][0])
    actor.eval()
    module = actor.as_onnx(verbose=False)
    module.eval()
    path = tmp_path / "policy.onnx"
    write_onnx(module, path)
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    inputs = sess.get_inputs()
    assert [i.name for i in inputs] == ["obs_window"]
    assert list(inputs[0].shape) == [1, H + 1, D]
    assert [o.name for o in sess.get_outputs()] == ["actions"]

    window = torch.randn(1, H + 1, D, generator=torch.Generator().manual_seed(10))
    (onnx_actions,) = sess.run(None, {"obs_window": window.numpy()})
    actor.deploy = True
    obs = with_nan_privileged(make_obs(n=1))
    obs["policy"], obs["history"] = window[:, 0], window[:, 1:]
    with torch.no_grad():
        torch_actions = actor(obs).numpy()
    np.testing.assert_allclose(onnx_actions, torch_actions, atol=1e-5)
    # the export is not constant in its input
    (other,) = sess.run(None, {"obs_window": (window + 1.0).numpy()})
    assert not np.allclose(other, onnx_actions)


def test_torchscript_export_is_refused_not_inherited_from_rsl_rl():
    with pytest.raises(NotImplementedError, match="ONNX only"):
        make_actor().as_jit()
