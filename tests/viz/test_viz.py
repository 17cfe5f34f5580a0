"""Cost curves of physics plans (viz/cost_curves.py) and apps/plan_scene.py's replay output,
serving and errors (the replay itself: test_replay.py; in a browser: test_browser.py)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from drake_clutter.planners.registry import get_planner
from drake_clutter.scene.scenes import DEFAULT_SCENE, load_shipped_scene
from drake_clutter.trajectory import Candidate
from drake_clutter.viz.cost_curves import plot_cost_curves, stage_curves
from drake_clutter.viz.views import static_html_paths

REPO = Path(__file__).resolve().parents[2]


def _stage(totals_terms, stop="converged"):
    """A stage record as physics._stage_record writes it, from per-iteration term dicts."""
    return {"iterations": len(totals_terms) - 1, "stop_reason": stop, "seconds": 1.0,
            "cost_history": [sum(t.values()) for t in totals_terms],
            "term_history": totals_terms, "timings": {}}


def _histories(candidate):
    """The cost histories the candidate's planner reads from its record."""
    return get_planner(candidate.planner).record(candidate.details).histories()


def _physics_candidate():
    pre = [{"c_static_hull": 10.0 / (i + 1), "c_vel": 0.5 + 0.01 * i, "c_dynamic": 0.0}
           for i in range(5)]
    full = [{"c_force": 1e4 * 0.1 ** i, "c_grasp": 2.0 - 0.2 * i} for i in range(4)]
    post = [{"c_static": 1.0, "c_match": 0.1 * i} for i in range(3)]
    details = {"stages": {"post": _stage(post), "pre": _stage(pre),
                          "full": _stage(full, "regularisation limit")}}
    return Candidate(0.25, "ok", planner="physics", details=details)


def test_stage_curves_read_the_physics_details_in_pipeline_order():
    curves = stage_curves(_histories(_physics_candidate()))
    assert [c.stage for c in curves] == ["pre", "full", "post"]
    pre = curves[0]
    np.testing.assert_array_equal(pre.iterations, np.arange(5))
    assert set(pre.terms) == {"c_static_hull", "c_vel", "c_dynamic"}
    np.testing.assert_allclose(pre.terms["c_static_hull"], 10.0 / np.arange(1, 6))
    np.testing.assert_allclose(pre.total, sum(pre.terms.values()))
    assert curves[1].stop_reason == "regularisation limit"


def test_no_curves_for_a_baseline_plan(tmp_path):
    baseline = Candidate(0.0, "ok", planner="baseline")
    assert stage_curves(_histories(baseline)) == []
    assert plot_cost_curves(_histories(baseline), tmp_path / "none.png") is None
    assert not (tmp_path / "none.png").exists()


def test_malformed_history_is_a_clear_error():
    candidate = _physics_candidate()
    candidate.details["stages"]["pre"]["term_history"].pop()
    with pytest.raises(ValueError, match="stage pre: 4 term records for 5 costs"):
        stage_curves(_histories(candidate))
    candidate = _physics_candidate()
    del candidate.details["stages"]["full"]["term_history"][2]["c_grasp"]
    with pytest.raises(ValueError, match="'c_grasp' missing"):
        stage_curves(_histories(candidate))


def test_cost_curve_png_has_one_panel_per_stage(tmp_path):
    path = plot_cost_curves(_histories(_physics_candidate()), tmp_path / "costs.png")
    assert path == tmp_path / "costs.png"
    image = imread(path)
    height, width = image.shape[:2]
    assert (height, width) == (380, 3 * 420)
    # Not blank: the curves in matplotlib's default colours (C0 blue, C1 orange) are drawn.
    rgb = image[..., :3]
    blue = np.all(np.abs(rgb - np.array([0x1f, 0x77, 0xb4]) / 255) < 0.05, axis=-1)
    orange = np.all(np.abs(rgb - np.array([0xff, 0x7f, 0x0e]) / 255) < 0.05, axis=-1)
    assert blue.sum() > 200 and orange.sum() > 200
    # and each third of the image (a panel) has some of them
    for third in np.array_split(blue | orange, 3, axis=1):
        assert third.sum() > 50


def test_unwritable_cost_curve_file_is_an_input_error(tmp_path):
    from drake_clutter.common.typed_yaml import InputError

    with pytest.raises(InputError, match="cannot write the cost curves"):
        plot_cost_curves(_histories(_physics_candidate()), tmp_path / "missing" / "costs.png")


# ----------------------------------------------------------------------------- apps/plan_scene.py


def _app(*args, timeout=600):
    return subprocess.run([sys.executable, "apps/plan_scene.py", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=timeout)


def test_plan_scene_baseline_writes_the_replay_html(tmp_path):
    out = tmp_path / "replay.html"
    result = _app("--planner", "baseline", "--html", str(out))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].split()[:3] == ["alpha", "baseline", "s"]
    assert len([ln for ln in lines if ln.strip().startswith(("+", "-"))]) == 2  # 2 angles
    assert "replay (" in result.stdout and f"wrote {out}" in result.stdout
    starred = [ln for ln in lines if ln.strip().startswith(("+", "-")) and "*" in ln]
    assert len(starred) == 1  # the candidate the baseline would execute
    assert "would execute (ranked without the judge): baseline alpha" in result.stdout
    paths = static_html_paths(out.read_text())
    for box in load_shipped_scene(DEFAULT_SCENE).boxes:
        assert f"/drake/illustration/boxes/{box.name}" in paths
    assert not any(p.startswith("/drake/illustration_") for p in paths)  # one planner, one copy
    assert "/drake/labels/baseline" in paths  # its name drawn in front of the shelf
    assert not list(tmp_path.glob("*.png"))  # no iLQR, no cost curves


def test_plan_scene_replays_the_selected_candidate(tmp_path):
    out = tmp_path / "selected.html"
    result = _app("--planner", "baseline", "--angles", "3", "--show", "selected",
                  "--html", str(out))
    assert result.returncode == 0, result.stderr
    starred = next(ln for ln in result.stdout.splitlines()
                   if ln.strip().startswith(("+", "-")) and "*" in ln)
    replay = next(ln for ln in result.stdout.splitlines() if ln.startswith("replay ("))
    assert f"baseline alpha {starred.split()[0]}" in replay
    assert out.exists()


def _terminal_sigint() -> None:
    """In the child before exec: SIGINT unblocked and at its default, as from a terminal.
    Both are inherited; in CI, after the whole suite, the app ignored the SIGINT below and
    never exited (twice, 2026-11-23; alone it exits at once), so something earlier in the
    pytest process leaves SIGINT blocked or ignored at the OS level."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_plan_scene_serves_and_prints_the_meshcat_url():
    process = subprocess.Popen([sys.executable, "apps/plan_scene.py", "--planner", "baseline"],
                               cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, preexec_fn=_terminal_sigint)
    try:
        deadline = time.monotonic() + 300
        url = ""
        while not url and time.monotonic() < deadline:
            line = process.stdout.readline()
            if not line:
                break
            if line.startswith("Meshcat: http://"):
                url = line.split()[1]
        assert url, "no Meshcat URL printed"
        assert "serving" in process.stdout.readline()
        assert process.poll() is None  # still serving
        with urllib.request.urlopen(url, timeout=30) as page:
            assert page.status == 200 and b"meshcat" in page.read().lower()
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=60) == 0
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


@pytest.mark.parametrize("args, field", [
    (["--angles", "0"], "--angles"),
    (["--html", "/no/such/dir/x.html"], "--html"),
    (["--costs", "/no/such/dir"], "--costs"),
    (["--angles", "3", "--angle", "3"], "--angle"),
    (["--iterations", "3", "--planner", "baseline", "push"], "--iterations"),
])
def test_plan_scene_bad_input_is_one_line_and_exit_2(args, field):
    result = _app(*args, timeout=120)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and field in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.slow
def test_plan_scene_shows_the_rearranged_plan_beside_both_others(tmp_path):
    out = tmp_path / "dense.html"
    result = _app("--scene", "dense_rearrange", "--planner", "baseline", "push", "rearrange",
                  "--angles", "14", "--angle", "8", "--html", str(out))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].split()[:7] == ["alpha", "rearrange", "s", "push", "s", "baseline", "s"]
    (row,) = [ln for ln in lines if ln.strip().startswith(("+", "-"))]  # one angle
    kinds = [cell.rstrip("*") for cell in row.split()[1:7:2]]
    assert kinds[0] == "success" and "success" not in kinds[1:], row
    paths = static_html_paths(out.read_text())
    for name in ("rearrange", "push", "baseline"):
        assert f"/drake/labels/{name}" in paths


def test_plan_scene_rejects_an_unknown_planner():
    result = _app("--planner", "magic", timeout=120)
    assert result.returncode == 2 and "invalid choice: 'magic'" in result.stderr


# ------------------------------------------------------------------ apps/behaviour_pictures.py


def _row(planner, angle, p, chosen="0.5"):
    return {"scene": "fig6_push_sideways", "planner": planner, "angle": angle, "config_hash": "h",
            "p_success": p, "plan": {"details": {"chosen": chosen}}}


def test_behaviour_pictures_picks_the_widest_win_then_a_bent_path():
    from drake_clutter.experiments.paired import widest_wins

    rows = [_row("baseline", 4, 0.625), _row("push", 4, 0.75),
            _row("baseline", 5, 0.0), _row("push", 5, 0.25),
            _row("baseline", 6, 0.0), _row("push", 6, 0.25, chosen="0.5/r0m1"),
            _row("baseline", 7, None), _row("push", 7, 1.0)]  # 7: not judged robustly
    ((base, push),) = widest_wins(rows, "push").values()
    assert (base["angle"], push["angle"]) == (6, 6)
    assert widest_wins(rows, "physics") == {}


@pytest.mark.parametrize("args, field", [
    (["missing.db", "--out", "."], "db"),
    (["missing.db", "--out", "/no/such/dir"], "--out"),
    (["missing.db", "--out", ".", "--frames", "0"], "--frames")])
def test_behaviour_pictures_bad_input_is_one_line_and_exit_2(args, field):
    result = subprocess.run([sys.executable, "apps/behaviour_pictures.py", *args], cwd=REPO,
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and field in result.stderr
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr


# ----------------------------------------------------------------------------- viz/labels.py


def test_a_label_is_the_word_with_its_holes_open():
    from drake_clutter.viz.labels import label_mesh, text_bitmap

    o = text_bitmap("O", 24)
    assert o.shape[0] == 24 and o.any()
    middle = o[12]
    filled = np.flatnonzero(middle)
    assert not middle[filled[0]:filled[-1] + 1].all()  # the hole of the O stays open
    mesh = label_mesh("push", 0.05)
    lo, hi = (np.array([v for v in mesh.vertices()]).min(axis=0),
              np.array([v for v in mesh.vertices()]).max(axis=0))
    assert lo[0] == hi[0] == 0.0  # flat in x = 0
    assert lo[2] >= 0.0 and hi[2] == pytest.approx(0.05)
    assert lo[1] == pytest.approx(-hi[1])  # centred in y
    with pytest.raises(ValueError):
        text_bitmap(" ", 24)
