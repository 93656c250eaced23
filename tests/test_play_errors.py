"""play.py's failures: a truncated or missing checkpoint and a viewer without a display end with
exit status 2 and a message, no traceback."""

from __future__ import annotations

import subprocess
import sys

from testkit import ROOT

from lasmp.cli.play import main


def test_truncated_checkpoint_exits_2(run_dir, tmp_path, capsys):
    bad = tmp_path / "model_5.pt"
    data = (run_dir / "model_0.pt").read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    assert main(["--checkpoint", str(bad), "--steps", "1"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "Traceback" not in err


def test_missing_checkpoint_exits_2_without_traceback(tmp_path):
    missing = tmp_path / "nope" / "model_3.pt"
    proc = subprocess.run(
        [sys.executable, str(ROOT / "play.py"), "--checkpoint", str(missing)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert proc.returncode == 2
    assert str(missing) in proc.stderr
    assert "Traceback" not in proc.stderr


def test_viewer_without_display_exits_with_message(run_dir, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["--checkpoint", str(run_dir), "--viewer"]) == 2
    assert "display" in capsys.readouterr().err.lower()
