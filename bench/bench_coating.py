"""Benchmark of the coating stage: speed on 100k vertices x 100k waypoints, occlusion methods, film uniformity
on real and demo panels, the spacing chooser against seed 000's overlap 0.4, and the droplet model.

Sections (all in one process; times are wall-clock medians over ``--repeat`` runs):

1. ``simulate`` on the demo roof (``select_region(car_roof(7.0), "z > 1000")``, about 100k vertices) with a
   plan of about 100k waypoints (``plan_paths`` at the chosen spacing, 1.55 mm step), per occlusion method.
2. Occlusion accuracy on reach_curved_part.ply: samples whose film each method changes, and the largest
   difference from exact rays at every time step (needs ``embreex``; skipped without it).
3. Film uniformity (std / mean, share of the painted area within 50 +- 5 um) on reach_curved_part.ply
   (--units m), the demo roof, noether_raw_scan_mesh.ply and the tray's top, planned with ``plan_paths`` at the
   spacing the chooser picks (and at seed 000's 49.19 mm), with and without the edge handling, the speed taken
   as the tool tip's (``tcp``) or the contact point's (``surface``); also away from the edges and at 420
   random points.
3b. (``--only plan``) The whole main job with a 50 um target on the demo roof, the reach part, the noether
   scan and the tray's top, with the planned speeds and with the speeds tuned to the film.
3c. (``--only tuning``) Tuning cost against quality: the solver's evaluations varied.
3d. (``--only touchups``) The touch-up stage piece by piece: new stations, chosen aims, the tuning's dead band.
4. Spacing chooser vs seed 000's fixed overlap 0.4 (spacing 49.19 mm for r = 50 mm), per pattern model.
5. Droplet model (bell003 settings): transfer efficiency, pattern radius, fits of the analytic models.

Usage::

    python bench/bench_coating.py [--repeat 3] [--skip-droplets] [--only SECTION]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))
from _data import meshes_dir  # noqa: E402 - bench/ is on sys.path when run as a script

from sprayplan.coating import (  # noqa: E402
    CoatingConfig,
    DropletConfig,
    SprayPattern,
    choose_spacing_and_speed,
    coating_report,
    fit_droplets,
    load_preset,
    ripple_cv,
    simulate,
    simulate_droplets,
    speed_for_target,
)
from sprayplan.config import PathConfig  # noqa: E402
from sprayplan.demo import car_roof  # noqa: E402
from sprayplan.io.load import load_part  # noqa: E402
from sprayplan.paths.planner import plan_paths  # noqa: E402
from sprayplan.surface.region import select_region  # noqa: E402


def has_embree() -> bool:
    import trimesh

    return bool(trimesh.ray.has_embree)


def seed_process():
    process = load_preset("seed000_circle")
    choice = choose_spacing_and_speed(process, 50.0)
    return process.with_(speed_mm_s=choice.speed_mm_s), choice


def timed(fn, repeat: int):
    """Median wall and CPU (this process, all threads) times over ``repeat`` runs, and the last result."""
    walls, cpus, out = [], [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        out = fn()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return statistics.median(walls), statistics.median(cpus), out


def section_speed(repeat: int) -> None:
    process, choice = seed_process()
    part = select_region(car_roof(resolution_mm=7.0), "z > 1000")
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm, step_mm=1.55))
    waypoints = sum(len(s) for s in paths.strokes)
    spray = sum(len(s) for s in paths.strokes if s.spray_on)
    print("## 1. Speed: demo roof, 100k vertices x 100k waypoints\n")
    print(f"{len(part.vertices)} vertices, {len(part.faces)} triangles; {waypoints} waypoints ({spray} spraying) in")
    print(f"{len(paths.strokes)} strokes; seed000_circle at spacing {choice.spacing_mm:.2f} mm, one time step per")
    print(f"waypoint (max_step_mm 5 > the 1.55 mm step). Medians of {repeat} runs of `simulate` (surface normals,")
    print("time steps, occlusion, deposit); CPU = this process's CPU time over all its threads.\n")
    print("'film samples': the mesh's vertices as they are (`sample_edge_mm=0`, the goal's 100k), or after the")
    print("default split of edges longer than R/5 = 10 mm (the roof's flanks have longer edges).\n")
    print("| occlusion | film samples | wall s | CPU s | painted std/mean | in spec |")
    print("|---|---|---|---|---|---|")
    methods = ["none", "raster", "zbuffer"] + (["rays"] if has_embree() else [])
    for edge in (0.0, None):
        for method in methods:
            config = CoatingConfig(occlusion=method, sample_edge_mm=edge)
            wall, cpu, result = timed(lambda c=config: simulate(part, paths, process, config=c), repeat)
            rep = coating_report(result)["painted"]
            print(
                f"| {method} | {len(result.points)} | {wall:.2f} | {cpu:.2f} | {rep['cv']:.4f} | "
                f"{rep['share_in_spec']:.4f} |"
            )
    if not has_embree():
        print("\n(rays: embreex not installed, not measured)")
    print()


def section_occlusion(repeat: int) -> None:
    print("## 2. Occlusion on reach_curved_part.ply (seed000_circle, chosen spacing, surface speed)\n")
    process, choice = seed_process()
    part = load_part(meshes_dir() / "reach_curved_part.ply", units="m")
    paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm))
    runs = {}
    samples = 0
    cases = [("none", None), ("raster", None), ("zbuffer", None)]
    if has_embree():
        cases += [("rays", None), ("rays", 0.0)]
    for method, step in cases:
        config = CoatingConfig(occlusion=method, occlusion_step_mm=step, speed_along="surface")
        wall, _, result = timed(lambda c=config: simulate(part, paths, process, config=c), repeat)
        runs[(method, step)] = (wall, result.thickness_um)
        samples = len(result.points)
    base = runs[("none", None)][1]
    exact = runs.get(("rays", 0.0), (None, None))[1]
    print(
        f"{samples} samples (the mesh split to 10 mm edges). Compared with exact rays (every time step its own view): 'missed' and"
    )
    print("'false' count samples whose film is more than 0.5 um too thick / too thin; 'captured' is the share of")
    print("the film that exact rays hide which the method hides too.\n")
    print("| method | view step | wall s | samples changed | missed | false | captured |")
    print("|---|---|---|---|---|---|---|")
    for (method, step), (wall, film) in runs.items():
        changed = int((np.abs(film - base) > 0.01).sum())
        if exact is not None:
            missed = int((film - exact > 0.5).sum())
            false = int((exact - film > 0.5).sum())
            captured = f"{(base - film).sum() / max((base - exact).sum(), 1e-12):.2f}"
        else:
            missed = false = captured = "n/a"
        shown = "every time step" if step == 0.0 else ("R/2.5 = 20 mm" if method != "none" else "-")
        print(f"| {method} | {shown} | {wall:.2f} | {changed} | {missed} | {false} | {captured} |")
    print()


def section_uniformity() -> None:
    print("## 3. Film uniformity (target 50 +- 5 um)\n")
    process, choice = seed_process()
    fixed_speed = speed_for_target(process.volume_rate_mm3_s, 49.19, 50.0)
    print(f"seed000_circle (parabolic, R = 50 mm at 113 mm). Chosen: spacing {choice.spacing_mm:.2f} mm, speed")
    print(f"{choice.speed_mm_s:.1f} mm/s (flat-panel ripple {100 * choice.cv:.2f} %); seed 000's overlap 0.4: spacing")
    print(f"49.19 mm, speed {fixed_speed:.1f} mm/s (ripple {100 * ripple_cv(process.pattern, 49.19):.2f} %). 'edges':")
    print("'on' = edge passes (outer and inner) and rims not followed (the defaults), 'off' = edge_passes 0 and")
    print("rim_mm 0. 'speed of': the process speed held by the tool tip (tcp) or by the contact point (surface).")
    print("'interior': painted samples more than one pattern radius (50 mm) from the part's open boundary. 420:")
    print("seed 003's check at 420 random painted points (seed 0). Film on the mesh split to 10 mm edges.\n")
    print(
        "| part | spacing | edges | speed of | strokes | painted std/mean | painted in spec | min-max um | "
        "interior std/mean | interior in spec | interior area share | 420 std/mean | 420 in spec |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    parts = {
        "reach_curved_part": (load_part(meshes_dir() / "reach_curved_part.ply", units="m"), "auto"),
        "demo roof z > 1000": (select_region(car_roof(), "z > 1000"), "auto"),
        "noether_raw_scan_mesh": (load_part(meshes_dir() / "noether_raw_scan_mesh.ply", units="m"), "auto"),
        "noether_raw_scan_mesh, direction x": (load_part(meshes_dir() / "noether_raw_scan_mesh.ply", units="m"), "x"),
        "tray top (z > 3.1)": (
            select_region(load_part(meshes_dir() / "tray_bottom_mm_ascii.stl", up="y"), "z > 3.1"),
            "auto",
        ),
    }
    cases = [
        ("chosen", choice.spacing_mm, choice.speed_mm_s, "on", "surface"),
        ("chosen", choice.spacing_mm, choice.speed_mm_s, "on", "tcp"),
        ("chosen", choice.spacing_mm, choice.speed_mm_s, "off", "surface"),
        ("chosen", choice.spacing_mm, choice.speed_mm_s, "off", "tcp"),
        ("49.19", 49.19, fixed_speed, "on", "surface"),
    ]
    for name, (part, direction) in parts.items():
        for label, spacing, speed, edges, along in cases:
            extra = {} if edges == "on" else {"edge_passes": 0, "rim_mm": 0.0}
            paths = plan_paths(part, PathConfig(spacing_mm=spacing, direction=direction, **extra))
            result = simulate(part, paths, process.with_(speed_mm_s=speed), config=CoatingConfig(speed_along=along))
            rep = coating_report(result, samples=420, edge_band_mm=50.0)
            p, i, m = rep["painted"], rep["interior"], rep["measuring_points"]
            print(
                f"| {name} | {label} | {edges} | {along} | {len(paths.spray_strokes)} | {p['cv']:.4f} | "
                f"{p['share_in_spec']:.4f} | {p['min_um']:.1f}-{p['max_um']:.1f} | {i['cv']:.4f} | "
                f"{i['share_in_spec']:.4f} | {i['share_of_area']:.3f} | {m['cv']:.4f} | {m['share_in_spec']:.4f} |"
            )
    print()


def section_plan_film(repeat: int = 3) -> None:
    """The film of the whole main job (``sprayplan plan PART --thickness-um 50 --simulate``), stations and all,
    with the planned speeds (``--no-tune-speed``) and with the speeds tuned to the film (the default)."""
    from sprayplan.coating.stage import meet_thickness, simulate_plan
    from sprayplan.config import JobConfig
    from sprayplan.export.summary import plan_totals
    from sprayplan.job import run_job
    from sprayplan.refine.stage import tune_plan

    def plan(part, job):
        return run_job(part, job, until="kinematics").plan

    print("### 3b. The main job: `sprayplan plan PART --thickness-um 50 --simulate` (defaults otherwise)\n")
    print("'speeds': as planned (`--no-tune-speed`) or tuned to the film with touch-up strokes (the default;")
    print("'touch-ups': how many were added). Tuning time: median of")
    print(f"{repeat} runs of `tune_plan` (deposit matrices, solves, touch-ups and their joints). 'interior': painted")
    print("samples more than 50 mm from the part's open boundary.\n")
    print(
        "| part | stations | strokes | touch-ups | waypoints | unreachable | speeds | painted std/mean | "
        "painted in spec | min-max um | interior std/mean | interior in spec | cycle s | tuning s | time factors |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, part in (
        ("demo roof z > 1000", select_region(car_roof(), "z > 1000")),
        ("reach_curved_part", load_part(meshes_dir() / "reach_curved_part.ply", units="m")),
        ("noether_raw_scan_mesh", load_part(meshes_dir() / "noether_raw_scan_mesh.ply", units="m")),
        ("tray top (z > 3.1)", select_region(load_part(meshes_dir() / "tray_bottom_mm_ascii.stl", up="y"), "z > 3.1")),
    ):
        job, _ = meet_thickness(JobConfig().replace(coating={"thickness_um": 50.0}))
        result = plan(part, job)
        tuning_wall, _, (tuned, info, _film, _) = timed(lambda p=part, r=result, j=job: tune_plan(p, r, j), repeat)
        for label, version, wall, factors in (
            ("planned", result, "-", "1"),
            ("tuned", tuned, f"{tuning_wall:.1f}", f"{info['dwell_min']:.2f}-{info['dwell_max']:.2f}"),
        ):
            report = coating_report(simulate_plan(part, version, job), edge_band_mm=50.0)
            film, inner = report["painted"], report["interior"]
            totals = plan_totals(version, job)
            cycle = totals["cycle_time_s"]
            touch_ups = sum(1 for st in version.stations for s in st.strokes if s.kind == "touch-up")
            print(
                f"| {name} | {totals['stations']} | {totals['strokes']} | {touch_ups} | {totals['waypoints']} | "
                f"{totals['unreachable_waypoints']} | {label} | "
                f"{film['cv']:.4f} | {film['share_in_spec']:.4f} | {film['min_um']:.1f}-{film['max_um']:.1f} | "
                f"{inner['cv']:.4f} | {inner['share_in_spec']:.4f} | {cycle:.0f} | {wall} | {factors} |"
            )
    print()


def section_tuning() -> None:
    """Tuning cost against quality: the solver's evaluations varied (``tune_speeds`` on the paths alone)."""
    from sprayplan.refine.tuning import TuningConfig, tune_speeds

    process, choice = seed_process()
    process = process.with_(speed_mm_s=choice.speed_mm_s)
    print("### 3c. Speeds tuned to the film: the solver's evaluations (30 is the default)\n")
    print(f"`tune_speeds` on `plan_paths` at {choice.spacing_mm:.2f} mm, one run each.\n")
    print("| part | evaluations | wall s | std/mean | in spec |")
    print("|---|---|---|---|---|")
    for name, part in (
        ("demo roof z > 1000", select_region(car_roof(), "z > 1000")),
        ("reach_curved_part", load_part(meshes_dir() / "reach_curved_part.ply", units="m")),
    ):
        paths = plan_paths(part, PathConfig(spacing_mm=choice.spacing_mm))
        for evaluations in (10, 20, 30, 50):
            start = time.perf_counter()
            tuning = tune_speeds(part, paths, process, 50.0, 5.0, config=TuningConfig(iterations=evaluations))
            wall = time.perf_counter() - start
            after = tuning.summary(50.0, 5.0)["after"]
            print(f"| {name} | {evaluations} | {wall:.1f} | {after['cv']:.4f} | {after['share_in_spec']:.4f} |")
    print()


def section_touch_ups() -> None:
    """What each part of the touch-up stage adds: the main job's tuning with the touch-ups' new stations,
    their aims and the tuning's dead band turned off one after another (``[tuning]`` settings)."""
    from sprayplan.coating.stage import meet_thickness
    from sprayplan.config import JobConfig
    from sprayplan.export.summary import plan_totals
    from sprayplan.job import run_job
    from sprayplan.refine.stage import tune_plan

    def plan(part, job):
        return run_job(part, job, until="kinematics").plan

    print("### 3d. The touch-up stage, piece by piece (main job, 50 um target)\n")
    print("Each row adds one piece to the row above; the last is the default. One run each; tuning s: `tune_plan`.")
    print("'stations': planned + added for touch-ups.\n")
    print("| part | variant | stations | touch-ups | painted std/mean | painted in spec | cycle s | tuning s |")
    print("|---|---|---|---|---|---|---|---|")
    variants = (
        (
            "touch-ups at planned stations only, no dead band",
            dict(touch_up_stations=0, touch_up_aim=False, band=0.0),
        ),
        ("+ new stations (up to 4)", dict(touch_up_aim=False, band=0.0)),
        ("+ aims chosen by the film model", dict(band=0.0)),
        ("+ dead band 0.3 tolerances (the default)", {}),
    )
    for name, part in (
        ("reach_curved_part", load_part(meshes_dir() / "reach_curved_part.ply", units="m")),
        ("noether_raw_scan_mesh", load_part(meshes_dir() / "noether_raw_scan_mesh.ply", units="m")),
        ("demo roof z > 1000", select_region(car_roof(), "z > 1000")),
    ):
        base, _ = meet_thickness(JobConfig().replace(coating={"thickness_um": 50.0}))
        result = plan(part, base)
        for label, changes in variants:
            job = base.replace(tuning=changes)
            start = time.perf_counter()
            tuned, info, film, _ = tune_plan(part, result, job)
            wall = time.perf_counter() - start
            report = coating_report(film, edge_band_mm=50.0)["painted"]
            totals = plan_totals(tuned, job)
            print(
                f"| {name} | {label} | {len(result.stations)} + {totals['stations'] - len(result.stations)} | "
                f"{info['touch_up_strokes']} | {report['cv']:.4f} | {report['share_in_spec']:.4f} | "
                f"{totals['cycle_time_s']:.0f} | {wall:.1f} |"
            )
    print()


def section_spacing() -> None:
    print("## 4. Spacing chooser vs seed 000's overlap 0.4 (flat panel, 1-D superposition)\n")
    print(
        "| pattern | chosen spacing mm | overlap | ripple std/mean | speed mm/s | ripple at 49.19 mm | "
        "speed at 49.19 mm |"
    )
    print("|---|---|---|---|---|---|---|")
    base = load_preset("seed000_circle")
    patterns = {
        "flat R50 (seed000_flat)": SprayPattern("flat", 50.0, 113.0),
        "parabolic R50 (seed000_circle)": SprayPattern("parabolic", 50.0, 113.0),
        "beta 1.5 R50": SprayPattern("beta", 50.0, 113.0, beta=1.5),
        "beta 3 R50": SprayPattern("beta", 50.0, 113.0, beta=3.0),
        "gaussian R50 sigma 16.7": SprayPattern("gaussian", 50.0, 113.0),
        "double beta a30 b60": SprayPattern("double_beta", a_mm=30.0, b_mm=60.0, beta1=2.0, beta2=2.5),
    }
    for name, pattern in patterns.items():
        process = base.with_(pattern=pattern)
        c = choose_spacing_and_speed(process, 50.0)
        fixed_speed = process.volume_rate_mm3_s / (49.19 * 0.05)
        print(
            f"| {name} | {c.spacing_mm:.2f} | {c.overlap:.3f} | {100 * c.cv:.2f} % | {c.speed_mm_s:.1f} | "
            f"{100 * ripple_cv(pattern, 49.19):.2f} % | {fixed_speed:.1f} |"
        )
    bell = load_preset("bell003")
    c = choose_spacing_and_speed(bell, 50.0)
    print(
        f"| bell003 (beta 1.9, R186 at 200) | {c.spacing_mm:.2f} | {c.overlap:.3f} | {100 * c.cv:.2f} % | "
        f"{c.speed_mm_s:.1f} | - | - |"
    )
    print()


def section_droplets() -> None:
    print("## 5. Droplet model (bell003: 40 krpm, SA2 180 L/min, 60 kV, cup 200 mm above the plate)\n")
    bell = load_preset("bell003")
    config = DropletConfig.from_bell(bell.bell, 200.0, count=3000, seed=0)
    start = time.perf_counter()
    result = simulate_droplets(config)
    elapsed = time.perf_counter() - start
    radius = np.linalg.norm(result.landing_mm[result.landed], axis=1)
    print(
        f"{config.count} droplets in {elapsed:.1f} s (Euler dt {config.dt_s:g} s): transfer efficiency "
        f"{result.transfer_efficiency:.3f}; landing radius median {np.median(radius):.0f} mm, 90 % "
        f"{np.quantile(radius, 0.9):.0f} mm, 99 % {np.quantile(radius, 0.99):.0f} mm.\n"
    )
    print("| model | fitted parameters | relative rms of the density fit |")
    print("|---|---|---|")
    for kind in ("flat", "parabolic", "beta", "gaussian"):
        fit = fit_droplets(result, kind, half_width_mm=200.0, cell_mm=10.0)
        params = ", ".join(f"{k} {v:.3g}" for k, v in fit.pattern.to_dict().items() if isinstance(v, float))
        print(f"| {kind} | {params} | {fit.relative_rms:.3f} |")
    print()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--skip-droplets", action="store_true")
    parser.add_argument(
        "--only", choices=["speed", "occlusion", "uniformity", "plan", "tuning", "touchups", "spacing", "droplets"]
    )
    args = parser.parse_args(argv)
    print(f"embreex available: {has_embree()}\n")
    sections = {
        "speed": lambda: section_speed(args.repeat),
        "occlusion": lambda: section_occlusion(args.repeat),
        "uniformity": section_uniformity,
        "plan": lambda: section_plan_film(args.repeat),
        "tuning": section_tuning,
        "touchups": section_touch_ups,
        "spacing": section_spacing,
        "droplets": section_droplets,
    }
    for name, run in sections.items():
        if args.only in (None, name) and not (name == "droplets" and args.skip_droplets and args.only is None):
            run()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
