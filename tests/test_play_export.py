"""play.py --export onnx: the exported model matches the torch policy and nothing else is said or
written, and an export needs --out."""

from __future__ import annotations

import logging
import os
import warnings

import numpy as np
import pytest
import torch

from lasmp.cli.play import main
from lasmp.deploy import obs_window


def test_export_onnx_matches_torch_and_says_nothing_else(run_dir, loaded, tmp_path, capsys):
    ort = pytest.importorskip("onnxruntime")
    from lasmp.modules.export import _TORCH_ONNX_REGISTRY_LOGGER

    logged = []
    registry = logging.getLogger(_TORCH_ONNX_REGISTRY_LOGGER)  # "torchvision is not installed" x 4
    handler = logging.Handler()
    handler.emit = logged.append
    registry.addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as warned:
            warnings.simplefilter("always")
            args = ["--checkpoint", str(run_dir), "--steps", "0", "--export", "onnx", "--out", str(tmp_path)]
            assert main(args) == 0
    finally:
        registry.removeHandler(handler)
    assert not logged and not warned, (logged, [str(w.message) for w in warned])
    path = tmp_path / "policy.onnx"
    out = capsys.readouterr().out
    assert str(path) in out
    assert "played" not in out  # an export alone plays no step, and says nothing of playing
    assert sorted(os.listdir(tmp_path)) == [
        "policy.json",
        "policy.onnx",
    ]  # the model and its sidecar, no temp file
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    assert [i.name for i in sess.get_inputs()] == ["obs_window"]
    env, policy, _, _ = loaded
    with torch.inference_mode():
        obs, *_ = env.step(torch.zeros(1, env.num_actions))  # a history that is not all o_0
        expected = policy(obs).numpy()
    (actions,) = sess.run(None, {"obs_window": obs_window(obs).numpy()})
    np.testing.assert_allclose(actions, expected, atol=1e-5)


def test_export_needs_out(run_dir):
    with pytest.raises(SystemExit) as exc:
        main(["--checkpoint", str(run_dir), "--export", "onnx"])
    assert exc.value.code == 2
