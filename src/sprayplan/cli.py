"""The ``sprayplan`` command: ``main(argv=None)`` with one subcommand per job.

Bad input ends with one line on stderr (``sprayplan: error: FILE: problem``), exit code 2, and no output file.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import time
from pathlib import Path

from sprayplan import __version__
from sprayplan.errors import ConfigError, InputError

log = logging.getLogger("sprayplan.cli")


def _add_load_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("part")
    group.add_argument("--units", choices=["mm", "cm", "m", "in"], default="mm", help="length unit of the file (default mm)")
    group.add_argument("--up", choices=["z", "y", "x"], default="z", help="the file's up axis, turned to +z (default z)")
    group.add_argument(
        "--region",
        help="keep only this region, in mm in the part frame: 'z > 1000', 'x < 500 and z > 1000', "
        "'box(x0,y0,z0,x1,y1,z1)'",
    )


def _add_target_options(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("targets")
    group.add_argument("--fill", choices=["even", "point", "line"], default="even", help="even (default), or the seed's DFS point or line filling")
    group.add_argument("--spacing-mm", type=float, help="target spacing d in mm (instead of --spray-radius-mm and --overlap)")
    group.add_argument("--spray-radius-mm", type=float, help="spray circle radius r in mm (default 50)")
    group.add_argument("--overlap", type=float, help="overlap ratio p of neighbouring spray circles (default 0.4)")
    group.add_argument("--compress", choices=["surface", "grid", "none"], default="surface", help="surface (default): one real point per eq. 7 cell; grid: eq. 7 as printed")
    group.add_argument("--h-min-mm", type=float, help="DFS filling: minimum triangle height (default: half the spacing)")
    group.add_argument("--normals", choices=["face", "pca"], default="face", help="even fill: face normals (default) or PCA over neighbours")
    group.add_argument("--normal-radius-mm", type=float, help="PCA neighbourhood radius (default: twice the spacing)")
    group.add_argument("--orient", choices=["mesh", "centroid", "propagate"], help="how normals are turned outward (default: mesh for meshes, propagate for clouds)")
    group.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def _targets_config(args):
    from sprayplan.config import TargetsConfig

    if args.spacing_mm is not None and (args.spray_radius_mm is not None or args.overlap is not None):
        raise ConfigError("give either --spacing-mm or --spray-radius-mm/--overlap, not both")
    extra = {}
    if args.spray_radius_mm is not None:
        extra["spray_radius_mm"] = args.spray_radius_mm
    if args.overlap is not None:
        extra["overlap"] = args.overlap
    return TargetsConfig(
        fill=args.fill,
        spacing_mm=args.spacing_mm,
        compress=args.compress,
        h_min_mm=args.h_min_mm,
        normals=args.normals,
        normal_radius_mm=args.normal_radius_mm,
        orient=args.orient,
        seed=args.seed,
        **extra,
    )


@contextlib.contextmanager
def _stage(name: str):
    start = time.perf_counter()
    log.info("%s ...", name)
    yield
    log.info("%s done in %.2f s", name, time.perf_counter() - start)


def _run_targets(part_path: str, output: Path, load_args, config) -> str:
    from sprayplan.io.load import load_part
    from sprayplan.io.writers import write_targets_csv
    from sprayplan.surface.region import select_region
    from sprayplan.surface.targets import make_targets

    start = time.perf_counter()
    with _stage("load"):
        part = load_part(part_path, units=load_args.units, up=load_args.up)
    with _stage("region"):
        part = select_region(part, load_args.region)
    with _stage("targets"):
        targets = make_targets(part, config)
    elapsed = time.perf_counter() - start
    write_targets_csv(output, targets)
    area = f"{part.area / 1e6:.4g} m^2" if part.is_mesh else f"a cloud of {len(part.vertices)} points"
    return (
        f"{len(targets)} targets on {area} (fill {config.fill if part.is_mesh else 'cloud'}, "
        f"spacing {config.spacing:.4g} mm, compress {config.compress}) in {elapsed:.2f} s -> {output}"
    )


def cmd_targets(args) -> int:
    config = _targets_config(args)
    print(_run_targets(args.part, Path(args.output), args, config))
    return 0


def cmd_demo(args) -> int:
    from sprayplan.config import TargetsConfig
    from sprayplan.demo import DEMO_REGION, car_roof
    from sprayplan.io.stl import write_stl_binary
    from sprayplan.io.writers import atomic_output

    out = Path(args.output)
    roof = car_roof()
    part_file = out / "roof.stl"
    with atomic_output(part_file, "wb") as handle:
        handle.write(write_stl_binary(roof.triangles, b"sprayplan demo car roof, mm, z up"))
    print(f"demo part: {part_file} ({len(roof.faces)} triangles, 2635 x 1959 mm above z = 1000 mm)")
    load_args = argparse.Namespace(units="mm", up="z", region=DEMO_REGION)
    print(_run_targets(str(part_file), out / "targets.csv", load_args, TargetsConfig()))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sprayplan",
        description="Turn a part's geometry into a spray-painting robot program.",
    )
    parser.add_argument("--version", action="version", version=f"sprayplan {__version__}")
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="log each stage and its time")
    common.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS, help="show errors only")
    parser.add_argument("-v", "--verbose", action="store_true", default=False, help="log each stage and its time")
    parser.add_argument("-q", "--quiet", action="store_true", default=False, help="show errors only")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser("demo", parents=[common], help="run the pipeline on the bundled car-roof part")
    demo.add_argument("-o", "--output", default="sprayplan-demo", help="output folder (default sprayplan-demo)")
    demo.set_defaults(func=cmd_demo)

    targets = sub.add_parser(
        "targets",
        parents=[common],
        help="target points with outward normals (CSV x,y,z,nx,ny,nz)",
        description="Target points on a part's surface with unit outward normals (seed 000, section 2).",
    )
    targets.add_argument("part", help="mesh (.stl .obj .ply .off, optionally .gz) or point cloud (.xyz .txt .csv .pcd .ply)")
    targets.add_argument("-o", "--output", required=True, help="output CSV file")
    _add_load_options(targets)
    _add_target_options(targets)
    targets.set_defaults(func=cmd_targets)
    return parser


class _Formatter(logging.Formatter):
    def format(self, record):
        level = "" if record.levelno == logging.INFO else f"{record.levelname.lower()}: "
        return f"sprayplan: {level}{record.getMessage()}"


def _setup_logging(verbose: bool, quiet: bool) -> logging.Handler:
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_Formatter())
    root = logging.getLogger("sprayplan")
    root.addHandler(handler)
    root.setLevel(logging.ERROR if quiet else logging.INFO if verbose else logging.WARNING)
    return handler


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    handler = _setup_logging(args.verbose, args.quiet)
    try:
        return args.func(args)
    except InputError as exc:
        print(f"sprayplan: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("sprayplan: interrupted", file=sys.stderr)
        return 130
    finally:
        logging.getLogger("sprayplan").removeHandler(handler)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
