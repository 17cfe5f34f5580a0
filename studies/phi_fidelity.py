"""How well phi predicts the judge: phi and Bullet on the same plans.

    python studies/phi_fidelity.py [--angles K] [--generated N --clutter M --seed S]
        [--set FIELD=VALUE ...] [--variant "FIELD=VALUE,FIELD=VALUE" ...] [--arm VARIANT]
        [--verbose]

The physics planner can only be as good as phi's prediction of what Bullet will do. The plans
are the baseline's: on each behaviour scene (Sec. VI-A) at its provenance angle, or with
``--angles K`` at K approach angles; ``--generated N`` adds N random bookshelf scenes of
``--clutter`` boxes (seeds ``--seed`` on). Each plan is replayed once in Bullet
(`judge.evaluate`: hard contacts, until the boxes rest) and rolled out in phi with every
box dynamic (no pruning), then ``--settle`` seconds with the arm held, once for the reference
configuration (``--set``) and once per ``--variant`` (overrides on top of it): the variants are
judged on the same plans and the same Bullet replays. Each box is classed as in Sec. III on
both final states: fallen (off the board), tipped (tilt over ``evaluation.max_tilt``) or
standing. A kinematic failure in Bullet stops its replay early, so its boxes are left out of
the classes; those plans are kept for the jams (below).

Printed per configuration: the boxes whose class agrees (all, and those that moved more than
1 cm in either engine: the ones that say something), the mean |displacement difference| of
the moved boxes (capped at 1 m), the boxes phi threw (moved over 1 m where Bullet moved them
under 30 cm: a box that phi launches off the board), phi's rollout seconds, and the
disagreements by class (Bullet's -> phi's). Jams: does phi see the arm push hard where Bullet
fails kinematically (Sec. III: the arm cannot follow, or presses the shelf through a box)?
phi's peak knot-mean contact force on the arm (`dynamics.Phi.contact_forces`' entry 0) over
the plan (up to Bullet's failure time plus a knot where it failed), over JAM_N or not, against
Bullet's kinematic failure or not, and the median peaks of both groups; and the judge's own
measure read in phi: the peak knot-mean force of a box on the shelf beyond its weight
(`Phi.shelf_forces`), over each of SHELF_THRESHOLDS_N. (A finger on the board
is c_static's matter: phi's arm passes through the shelf.)

Its dated results: docs/log/phi.md.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field, replace

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.robot.pr2 import VARIANTS
from drake_clutter.scene import scenes
from drake_clutter.scene.generators import generate_scene
from drake_clutter.testing.fidelity import classes, phi_final

SCENES = ("fig5_large_small", "fig6_push_sideways", "fig7_cascade", "fig8_snaking")
MOVED_CM = 1.0  # a box that moved less than this in both engines says nothing
THROWN_CM, SHORT_CM = 100.0, 30.0  # phi over THROWN_CM where Bullet under SHORT_CM: thrown
JAM_N = 50.0  # N: phi's peak arm force that "predicts" a kinematic failure (Sec. III's 50 N)
SHELF_THRESHOLDS_N = (2.0, 5.0, 10.0, 20.0, 50.0)  # phi's box-on-shelf excess read as a jam


def _median_n(values: np.ndarray) -> str:
    return f"{np.median(values):.0f} N" if len(values) else "-"


@dataclass
class Tally:
    """One configuration's agreement with Bullet, summed over plans."""

    agree: int = 0
    boxes: int = 0
    moved_agree: int = 0
    moved: int = 0
    thrown: int = 0
    seconds: float = 0.0
    errors: list = field(default_factory=list)
    confusion: dict = field(default_factory=dict)  # (Bullet class, phi class) -> boxes
    peaks: dict = field(default_factory=lambda: {True: [], False: []})  # Bullet kinematic
    # failure? -> phi's peak arm forces (N)
    shelf: dict = field(default_factory=lambda: {True: [], False: []})  # the same -> phi's
    # peak box-on-shelf force beyond the box's weight (N)

    def line(self, label: str) -> str:
        error = float(np.mean(self.errors)) if self.errors else 0.0
        return (f"{label:40} classes {self.agree:3d}/{self.boxes:<3d} moved boxes "
                f"{self.moved_agree:3d}/{self.moved:<3d} |d| {error:5.1f} cm thrown "
                f"{self.thrown:2d} phi {self.seconds:6.1f} s")

    def jams(self) -> str:
        """phi's peak arm force against Bullet's kinematic failures."""
        kf, ok = (np.array(self.peaks[k]) for k in (True, False))
        return (f"jams: phi's arm over {JAM_N:.0f} N in {int(np.sum(kf > JAM_N))}/{len(kf)} "
                f"Bullet kinematic failures and {int(np.sum(ok > JAM_N))}/{len(ok)} other "
                f"plans; median peak {_median_n(kf)} vs {_median_n(ok)}")

    def shelf_jams(self) -> str:
        """phi's peak box-on-shelf excess (the judge's own measure) against Bullet's kinematic
        failures, at each of SHELF_THRESHOLDS_N."""
        kf, ok = (np.array(self.shelf[k]) for k in (True, False))
        hits = ", ".join(f"{t:g} N: {int(np.sum(kf > t))}/{len(kf)} vs {int(np.sum(ok > t))}"
                         f"/{len(ok)}" for t in SHELF_THRESHOLDS_N)
        return (f"box on shelf beyond its weight, kinematic failures vs other plans over "
                f"{hits}; median peak {_median_n(kf)} vs {_median_n(ok)}")

    def misses(self) -> str:
        """The disagreements, as 'Bullet class -> phi class: boxes'."""
        return ", ".join(f"{b} -> {p}: {n}" for (b, p), n in sorted(self.confusion.items())
                         if b != p)


@dataclass
class Replay:
    """A plan and its Bullet result: what every configuration's phi is compared with."""

    label: str
    scene: object
    trajectory: object
    start: np.ndarray
    p_bullet: np.ndarray
    tilt_bullet: np.ndarray
    kind: str
    fail_time: float | None = None  # s: Bullet's kinematic failure, None if none

    @property
    def failed(self) -> bool:
        """Whether Bullet found a kinematic failure (its replay stopped there)."""
        return self.fail_time is not None


def replays(scene_list, angles: int, config) -> list[Replay]:
    """The baseline's plans on each scene (its provenance angle, or ``angles`` angles), each
    replayed in Bullet (a kinematic failure is marked by its time: said so)."""
    out = []
    for name, scene in scene_list:
        if angles == 1 and scene.provenance and "alpha" in scene.provenance.parameters:
            alphas = [float(scene.provenance.parameters["alpha"])]
        else:
            alphas = approach_angles(replace(config.baseline, num_angles=angles))
        for candidate in plan_baseline(scene, config.baseline, alphas=alphas):
            label = f"{name} alpha {candidate.alpha:+.2f}"
            if not candidate.ok:
                print(f"{label}: no baseline plan ({candidate.reason})")
                continue
            o = evaluate(scene, candidate.trajectory, config.evaluation)
            fail_time = None
            if o.kind == "kinematic_failure":
                print(f"{label}: kinematic failure in Bullet at {o.simulated_time:.2f} s "
                      f"({o.reason}): jams only")
                fail_time = o.simulated_time
            start = np.array([[b.pose[0], b.pose[1], scene.box_center_z(b)]
                              for b in scene.boxes])
            out.append(Replay(label, scene, candidate.trajectory, start,
                              np.array([b.final_position for b in o.boxes]),
                              np.array([b.tilt for b in o.boxes]), o.kind, fail_time))
    return out


def compare(replay: Replay, config, settle: float, tally: Tally, verbose: bool,
            arm: str = "capsules") -> None:
    """Rolls one plan out in phi under ``config`` and adds its agreement to ``tally``."""
    scene, max_tilt = replay.scene, config.evaluation.max_tilt
    p_phi, tilt_phi, seconds, peak, shelf_peak = phi_final(scene, replay.trajectory, config,
                                                           settle, arm, replay.fail_time)
    tally.seconds += seconds
    tally.peaks[replay.failed].append(peak)
    tally.shelf[replay.failed].append(shelf_peak)
    if replay.failed:
        if verbose:
            print(f"\n{replay.label}: Bullet {replay.kind} at {replay.fail_time:.2f} s; "
                  f"phi's peak arm force {peak:.0f} N")
        return
    c_bullet = classes(scene, replay.p_bullet, replay.tilt_bullet, max_tilt)
    c_phi = classes(scene, p_phi, tilt_phi, max_tilt)
    moved_b = np.linalg.norm(replay.p_bullet - replay.start, axis=1) * 100
    moved_p = np.nan_to_num(np.linalg.norm(p_phi - replay.start, axis=1) * 100, nan=1e9)
    agree = np.array([a == b for a, b in zip(c_bullet, c_phi, strict=True)])
    moving = (moved_b > MOVED_CM) | (moved_p > MOVED_CM)
    tally.agree += int(agree.sum())
    tally.boxes += len(agree)
    tally.moved_agree += int(agree[moving].sum())
    tally.moved += int(moving.sum())
    tally.thrown += int(np.sum((moved_p > THROWN_CM) & (moved_b < SHORT_CM)))
    tally.errors.extend(np.minimum(np.abs(moved_b - moved_p), 100.0)[moving])
    for b, p in zip(c_bullet, c_phi, strict=True):
        tally.confusion[b, p] = tally.confusion.get((b, p), 0) + 1
    if verbose:
        print(f"\n{replay.label}: Bullet {replay.kind}; phi rollout {seconds:.1f} s, peak "
              f"arm force {peak:.0f} N")
        print(f"  {'box':16} {'Bullet':>8} {'cm':>6} {'deg':>4} | {'phi':>8} {'cm':>6} {'deg':>4}")
        for i, box in enumerate(scene.boxes):
            print(f"  {box.name:16} {c_bullet[i]:>8} {moved_b[i]:6.1f} "
                  f"{np.degrees(replay.tilt_bullet[i]):4.0f} | {c_phi[i]:>8} "
                  f"{min(moved_p[i], 999.9):6.1f} {np.degrees(tilt_phi[i]):4.0f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--angles", type=int, default=1,
                        help="baseline angles per scene (1: the scene's provenance angle)")
    parser.add_argument("--generated", type=int, default=0, help="random bookshelf scenes")
    parser.add_argument("--clutter", type=int, default=10, help="boxes per generated scene")
    parser.add_argument("--seed", type=int, default=0, help="first generated scene's seed")
    parser.add_argument("--settle", type=float, default=2.0, help="s the arm holds after the plan")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    parser.add_argument("--variant", action="append", default=[],
                        metavar="FIELD=VALUE[,FIELD=VALUE]")
    parser.add_argument("--arm", default="capsules", choices=VARIANTS,
                        help="phi's arm geometry (the planner's full stage: capsules)")
    parser.add_argument("--verbose", action="store_true", help="every box of every plan")
    args = parser.parse_args(argv)
    if args.angles < 1 or args.generated < 0:
        parser.error("--angles must be >= 1 and --generated >= 0")
    config = load_config(None, args.set)
    variants = [("reference " + " ".join(args.set), config)] + [
        (v, load_config(None, [*args.set, *v.split(",")])) for v in args.variant]
    scene_list = [(n, scenes.load_shipped_scene(n)) for n in args.scenes] + [
        (f"bookshelf{args.clutter}-{s}", generate_scene("bookshelf", args.clutter, s))
        for s in range(args.seed, args.seed + args.generated)]
    print(f"phi: {config.dynamics.substeps} sub-steps a {config.baseline.knot_time} s knot, "
          f"modulus {config.world.hydroelastic_modulus:g} Pa")
    plans = replays(scene_list, args.angles, config)
    failed = sum(r.failed for r in plans)
    print(f"{len(plans)} plans replayed in Bullet ({failed} kinematic failures)")
    tallies = [Tally() for _ in variants]
    for replay in plans:
        for (_, cfg), tally in zip(variants, tallies, strict=True):
            compare(replay, cfg, args.settle, tally, args.verbose and cfg is config, args.arm)
    print()
    for (label, _), tally in zip(variants, tallies, strict=True):
        print(tally.line(label))
        print(f"{'':40} misses: {tally.misses()}")
        print(f"{'':40} {tally.jams()}")
        print(f"{'':40} {tally.shelf_jams()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
