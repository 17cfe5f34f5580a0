"""The drake-clutter command line and apps/plan_scene.py: outputs, exit codes, one-line errors."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from drake_clutter.cli import main
from drake_clutter.scene.scenes import (
    DEFAULT_SCENE,
    load_scene,
    load_shipped_scene,
    shipped_scene_names,
)
from drake_clutter.viz.views import static_html_paths

REPO = Path(__file__).resolve().parents[1]


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "drake_clutter.cli", *args], cwd=REPO,
                          capture_output=True, text=True, timeout=300)


def test_generate_validate_round_trip(tmp_path, capsys):
    out = tmp_path / "s.yaml"
    assert main(["scene", "generate", "--kind", "fridge", "--objects", "8", "--seed", "3",
                 "-o", str(out)]) == 0
    scene = load_scene(out)
    assert len(scene.boxes) == 8 and scene.shelf.kind == "fridge"
    assert main(["scene", "validate", str(out)]) == 0
    assert "ok" in capsys.readouterr().out


def test_generate_with_config_override(tmp_path):
    out = tmp_path / "s.yaml"
    assert main(["scene", "generate", "--kind", "bookshelf", "--objects", "3", "--seed", "1",
                 "-o", str(out), "--set", "generator.board_top_height=0.9"]) == 0
    assert load_scene(out).shelf.top_height == 0.9


def test_list_shows_every_shipped_scene(capsys):
    assert main(["scene", "list"]) == 0
    text = capsys.readouterr().out
    for name in shipped_scene_names():
        assert name in text


@pytest.mark.parametrize("args,needle", [
    (["scene", "validate", "no/such/file.yaml"], "no such file"),
    (["scene", "show", "no_such_scene"], "no shipped scene"),
    (["scene", "generate", "--kind", "fridge", "--objects", "0", "--seed", "1", "-o", "x.yaml"],
     "--objects"),
    (["scene", "generate", "--kind", "fridge", "--objects", "2", "--seed", "1", "-o", "x.yaml",
      "--set", "generator.nope=1"], "unknown key"),
    (["scene", "generate", "--kind", "cupboard", "--objects", "2", "--seed", "1", "-o", "x"],
     "invalid choice"),
    (["scene", "frobnicate"], "invalid choice"),
    (["scene", "generate", "--kind", "fridge", "--objects", "2", "--seed", "-1", "-o", "x.yaml"],
     "--seed"),
    (["scene", "generate", "--kind", "fridge", "--objects", "2", "--seed", "1", "-o",
      "/no/such/dir/x.yaml"], "cannot write"),
    (["experiment", "run", "nope_tier", "--db", "x.db"], "tiers: smoke, small"),
])
def test_bad_input_gives_one_line_and_exit_2(args, needle, tmp_path):
    result = _run(*args)
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], result.stderr
    assert "Traceback" not in result.stderr


def test_impossible_generation_is_bad_input(tmp_path):
    """Too many boxes for the board is a bad --objects: one line, exit 2, no file."""
    out = tmp_path / "x.yaml"
    result = _run("scene", "generate", "--kind", "fridge", "--objects", "40", "--seed", "1",
                  "-o", str(out), "--set", "generator.max_attempts=1",
                  "--set", "generator.max_redraws_per_box=2")
    assert result.returncode == 2 and "could not place" in result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--objects" in lines[0] and not out.exists()


def test_bad_scene_file_names_file_and_field(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text((REPO / "drake_clutter/scene/shipped/fig5_large_small.yaml").read_text()
                   .replace("density: 150.0", "density: -150.0"))
    result = _run("scene", "validate", str(bad))
    assert result.returncode == 2
    assert str(bad) in result.stderr and "boxes[2].density" in result.stderr
    assert "Traceback" not in result.stderr


def test_scene_show_writes_html(tmp_path):
    out = tmp_path / "view.html"
    result = _run("scene", "show", "fig8_snaking", "--html", str(out))
    assert result.returncode == 0, result.stderr
    html = out.read_text()
    assert "<html" in html.lower()
    paths = static_html_paths(html)
    scene = load_shipped_scene("fig8_snaking")
    for box in scene.boxes:
        assert f"/drake/illustration/boxes/{box.name}" in paths
    assert "/drake/illustration/shelf/shelf_link" in paths
    assert "/drake/illustration/pr2_arm/r_upper_arm_roll_link" in paths
    assert "/drake/illustration/pr2_arm/r_gripper_l_finger_link" in paths


def test_plan_scene_app_writes_html_of_default_scene(tmp_path):
    out = tmp_path / "default.html"
    result = subprocess.run([sys.executable, "apps/plan_scene.py", "--html", str(out)], cwd=REPO,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    paths = static_html_paths(out.read_text())
    for box in load_shipped_scene(DEFAULT_SCENE).boxes:
        assert f"/drake/illustration/boxes/{box.name}" in paths
    # The default scene shows what the push planner is for: at -0.5 rad the path its search
    # returns succeeds where the baseline's straight one jams, and the replay shows that angle.
    row = next(line for line in result.stdout.splitlines() if line.startswith(" -0.500"))
    assert row.split()[1:2] == ["success"] and "kinematic_failure" in row and "search=" in row
    assert ("replay" in result.stdout and "push alpha -0.500 (success) right" in result.stdout
            and "baseline alpha -0.500 (kinematic_failure) left" in result.stdout)


@pytest.mark.parametrize("args, field", [(["--jobs", "0"], "--jobs"),
                                         (["--angles", "0"], "--angles"),
                                         (["--set", "physics.iterations=-1"], "physics"),
                                         (["--set", "phi_judge.members=0"], "phi_judge.members"),
                                         (["--iterations", "30"], "--iterations"),
                                         (["--planner", "nope"], "--planner"),
                                         (["--jobs", "two"], "--jobs")])
def test_plan_scene_app_bad_options_exit_2(args, field):
    result = subprocess.run([sys.executable, "apps/plan_scene.py", *args, "--no-browser"],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and field in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


@pytest.mark.parametrize("app, args", [
    ("apps/screenshot.py", ["--size", "big", "a.html", "b.png"]),
    ("apps/behaviour_pictures.py", ["--frames", "many", "x.db", "--out", "o"]),
    ("apps/screenshot.py", []),
])
def test_every_app_reports_a_bad_argument_in_one_line(app, args):
    result = subprocess.run([sys.executable, app, *args], cwd=REPO, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr


def test_a_picture_without_chromium_is_refused_before_planning(tmp_path):
    """No chromium on PATH: one line naming --picture and the package, exit 2, in seconds
    (nothing planned)."""
    bare = tmp_path / "bin"  # a PATH with no chromium on it
    bare.mkdir()
    result = subprocess.run([sys.executable, "apps/plan_scene.py", "--picture",
                             str(tmp_path / "p.png"), "--no-browser"], cwd=REPO,
                            capture_output=True, text=True, timeout=120,
                            env={**os.environ, "PATH": str(bare)})
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--picture" in lines[0] and "apt-get install chromium" in lines[0]
    assert "alpha" not in result.stdout  # no table: nothing was planned


def test_plan_scene_app_bad_scene_exit_2():
    result = subprocess.run([sys.executable, "apps/plan_scene.py", "--scene", "missing.yaml"],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 2 and "no such file" in result.stderr
    assert "Traceback" not in result.stderr
