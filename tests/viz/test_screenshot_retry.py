"""viz.screenshot: a headless Chromium that hangs is killed and started again, then reported."""

import subprocess

import pytest

from drake_clutter.viz import screenshot as shot


def test_a_hung_chromium_is_started_again_then_reported(tmp_path, monkeypatch):
    calls = []

    def hangs_once(html, png, window, budget_ms, timeout_s):
        calls.append(timeout_s)
        if len(calls) == 1:
            raise subprocess.TimeoutExpired("chromium", timeout_s)
        png.write_bytes(b"png")
        return subprocess.CompletedProcess([], 0, "", "")

    monkeypatch.setattr(shot, "_chromium", hangs_once)
    png = tmp_path / "shot.png"
    assert shot.screenshot(tmp_path / "page.html", png, timeout_s=5.0) == png
    assert calls == [5.0, 5.0] and png.read_bytes() == b"png"

    def always_hangs(html, png, window, budget_ms, timeout_s):
        raise subprocess.TimeoutExpired("chromium", timeout_s)

    monkeypatch.setattr(shot, "_chromium", always_hangs)
    with pytest.raises(RuntimeError, match="did not finish in 5 s, 2 times"):
        shot.screenshot(tmp_path / "page.html", png, timeout_s=5.0)
    assert not png.exists()
