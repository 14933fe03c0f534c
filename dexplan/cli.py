"""The ``dexplan`` command line.

Exit codes: 0 success (plan found, plan verified), 1 no plan within the time
limit or a plan that fails verification, 2 bad input (malformed scenario or
plan file, unknown planner, missing file, non-finite number).

Progress and errors go to stderr, results to stdout. Library code never prints;
this module owns all output.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from importlib import metadata

from dexplan.exceptions import DexplanError

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_BAD_INPUT = 2

EPILOG = """exit codes:
  0  success
  1  no plan found within the time limit, or the plan fails verification
  2  bad input (malformed scenario or plan, unknown planner, missing file)
"""


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def cmd_info(args: argparse.Namespace) -> int:
    """Print the builtin hand, the default object and dependency versions."""
    from dexplan.hand import Hand  # noqa: PLC0415 - keep `--help` fast
    from dexplan.objects import Sphere  # noqa: PLC0415

    hand = Hand.builtin(args.hand)
    out = sys.stdout
    out.write(f"dexplan {_version('dexplan')}\n")
    out.write(
        f"hand: {hand.name}: {hand.n_fingers} fingers, {hand.nq} joints, "
        f"fingertip radius {hand.fingertip_radius} m\n"
    )
    for i, idx in enumerate(hand.finger_q_index):
        joints = ", ".join(
            f"{hand.joint_names[j]} [{hand.lower[j]:+.2f}, {hand.upper[j]:+.2f}]" for j in idx
        )
        out.write(f"  finger {i} ({hand.fingertip_frames[i]}): {joints}\n")
    obj = Sphere(0.04)
    out.write(f"object: {obj.to_dict()}\n")
    for dist in ("ompl", "pin", "coal", "osqp", "numpy", "scipy", "trimesh", "rerun-sdk"):
        out.write(f"{dist}: {_version(dist)}\n")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``dexplan`` command."""
    parser = argparse.ArgumentParser(
        prog="dexplan",
        description="Dexterous in-hand manipulation planning in the n-finger grasp subspace.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=_version("dexplan"))
    sub = parser.add_subparsers(dest="command", required=True)

    p_info = sub.add_parser("info", help="show the builtin hand, object and dependency versions")
    p_info.add_argument("--hand", default="paper", help="builtin hand name (default: paper)")
    p_info.set_defaults(func=cmd_info)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``dexplan`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = int(args.func(args))
    except DexplanError as exc:
        sys.stderr.write(f"dexplan: error: {exc}\n")
        code = EXIT_BAD_INPUT
    except KeyboardInterrupt:
        sys.stderr.write("dexplan: interrupted\n")
        code = 130
    sys.stdout.flush()
    sys.stderr.flush()
    # nanobind (ompl) reports "leaked instances" at interpreter exit; users
    # should not see it, and everything is flushed already.
    os._exit(code)


if __name__ == "__main__":
    main()
