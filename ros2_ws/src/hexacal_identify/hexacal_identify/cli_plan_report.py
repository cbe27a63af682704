"""``hexacal plan`` (choose measuring postures) and ``hexacal report`` (HTML page of a calibration result)."""
from __future__ import annotations

import json
import math
from pathlib import Path

from typing import TYPE_CHECKING

from .cli_common import Progress, load_params_arg

if TYPE_CHECKING:
    from .core.planning import PostureLimits

# The planner and the report are imported where they run: this module is imported by every `hexacal` start-up to
# register the commands.


def add_parsers(subparsers) -> None:
    subparsers.add_parser(
        "plan",
        help="choose K measuring postures that maximise an observability index; write a plan file",
        description="Draw feasible candidate postures (sphere and fixed-position, within the inclinometer range, "
        "slider stroke, U/S-joint limits, away from singularities), score them with the identification Jacobian "
        "at the nominal parameters and choose K that maximise the observability index. Writes the driver's "
        "plan-file format (YAML, SI units) atomically.",
        fill=_plan_arguments,
    )
    subparsers.add_parser(
        "report",
        help="write a self-contained HTML report (PNG figures) of a calibration result",
        description="Read a result JSON (from report.save_result, or the output of `hexacal calibrate --json` / "
        "`hexacal study --json`, which gives fewer figures) and write DIR/index.html with its figures.",
        fill=_report_arguments,
    )


def _plan_arguments(plan) -> None:
    from .core.device import DEFAULT_LINK_LENGTH_M
    from .core.planning import CRITERIA, METHODS, PostureLimits
    from .core.residuals import COSTS

    plan.add_argument("--postures", type=int, required=True, help="number of postures K to choose")
    plan.add_argument("--index", choices=CRITERIA, default="O1",
                      help="O1 D-optimal (default), O2 inverse condition number, O3 smallest singular value, "
                      "O4 noise amplification index, I least predicted position error over the workspace")
    plan.add_argument("--method", choices=METHODS, default="greedy",
                      help="greedy (default), or exchange: greedy followed by Fedorov-style swaps")
    plan.add_argument("--candidates", type=int, default=2000, help="candidate postures to choose from (default 2000)")
    plan.add_argument("--cost", choices=COSTS, default="absolute", help="cost function to plan for (default absolute)")
    plan.add_argument("--nominal", type=Path, help="parameters YAML of the nominal model (default: Table 1)")
    plan.add_argument("--seed", type=int, default=0, help="seed of the candidate draw (default 0)")
    plan.add_argument("--name", help="plan name (default: method-index-K-fingerprint)")
    plan.add_argument("--noise-um", type=float, default=10.0,
                      help="weight rows by the reading noise: +-X um sliders, +-X urad angles (default 10; only "
                      "the slider/angle ratio matters)")
    plan.add_argument("--unweighted", action="store_true",
                      help="plan on the plain (unweighted) identification Jacobian")
    plan.add_argument("--fixed-fraction", type=float,
                      help="share of fixed-position candidates (default: 0.25 for sphere-fixed/relative, 1 for "
                      "fixed, else 0)")
    defaults = PostureLimits()
    plan.add_argument("--link-length", type=float, default=DEFAULT_LINK_LENGTH_M, help="device link length L, m")
    plan.add_argument("--xy-range-mm", type=float, default=defaults.xy_range_m * 1e3, help="|x|, |y| limit (default 400)")
    plan.add_argument("--rotation-range-deg", type=float, default=math.degrees(defaults.rotation_range_rad),
                      help="|theta|, |psi|, |phi| limit (default 35)")
    plan.add_argument("--inclinometer-range-deg", type=float, default=math.degrees(defaults.inclinometer_range_rad),
                      help="inclinometer range (default 45)")
    plan.add_argument("--slider-stroke-m", type=float, nargs=2, default=list(defaults.slider_stroke_m),
                      metavar=("MIN", "MAX"), help="slider stroke (default 0 0.9)")
    plan.add_argument("--max-u-joint-deg", type=float, default=math.degrees(defaults.max_u_joint_angle_rad),
                      help="max angle between leg and rail at the U joint (default 60)")
    plan.add_argument("--max-s-joint-deg", type=float, default=math.degrees(defaults.max_s_joint_angle_rad),
                      help="max angle between leg and platform normal at the S joint (default 90)")
    plan.add_argument("--max-condition", type=float, default=defaults.max_condition,
                      help="max pose-Jacobian condition number, angles scaled by L (default 80)")
    plan.add_argument("--out", type=Path, required=True, help="plan file to write (YAML)")
    plan.add_argument("--json", action="store_true", help="print one JSON object (no progress display)")
    plan.set_defaults(handler=run_plan)


def _report_arguments(report) -> None:
    report.add_argument("result", type=Path, help="result JSON file")
    report.add_argument("--out", type=Path, required=True, help="output directory")
    report.add_argument("--title", help="page title")
    report.set_defaults(handler=run_report)


def _limits(args) -> PostureLimits:
    from .core.planning import PostureLimits

    low, high = args.slider_stroke_m
    return PostureLimits(
        link_length=args.link_length, xy_range_m=args.xy_range_mm / 1e3,
        rotation_range_rad=math.radians(args.rotation_range_deg),
        inclinometer_range_rad=math.radians(args.inclinometer_range_deg), slider_stroke_m=(low, high),
        max_u_joint_angle_rad=math.radians(args.max_u_joint_deg),
        max_s_joint_angle_rad=math.radians(args.max_s_joint_deg), max_condition=args.max_condition,
    )


def run_plan(args) -> int:
    from .core.measurements import NoiseModel
    from .core.model import N_PARAMETERS, table1_parameters
    from .core.planning import INDICES, PREDICTION, plan_postures

    nominal = load_params_arg(args.nominal) if args.nominal else table1_parameters()
    if args.out.is_dir():
        raise IsADirectoryError(f"--out {args.out} is a directory; name a YAML file")
    weighted = not args.unweighted and args.cost != "relative" and args.noise_um > 0
    noise = NoiseModel.from_microns(args.noise_um) if weighted else None
    steps = args.postures * (2 if args.method == "exchange" else 1) + 1
    progress = Progress(enabled=not args.json, total=steps)
    try:
        planning = plan_postures(nominal, args.postures, index=args.index, method=args.method,
                                 n_candidates=args.candidates, cost=args.cost, limits=_limits(args),
                                 fixed_fraction=args.fixed_fraction, seed=args.seed, noise=noise, name=args.name,
                                 progress=progress.step)
    finally:
        progress.close()
    random = planning.random_indices()
    planning.plan.metadata["random_mean_indices"] = random
    planning.plan.save(args.out)
    plan = planning.plan
    counts = {kind: int((plan.kinds == kind).sum()) for kind in ("sphere", "fixed")}
    if args.json:
        print(json.dumps({
            "out": str(args.out), "name": plan.name, "postures": len(plan), "kinds": counts,
            "index": args.index, "method": args.method, "cost": args.cost, "weighted": weighted,
            "candidates": len(planning.candidates), "rank": planning.rank, "indices": planning.indices, "random_mean_indices": random,
            "candidate_seconds": planning.candidate_seconds, "selection_seconds": planning.selection_seconds,
            "exchange_swaps": max(len(planning.exchange_history) - 1, 0),
        }))
        return 0
    print(f"plan '{plan.name}': {len(plan)} postures ({counts['sphere']} sphere, {counts['fixed']} fixed) chosen "
          f"from {len(planning.candidates)} candidates by {args.method} on {args.index} "
          f"({'noise-weighted' if weighted else 'unweighted'}, cost {args.cost})")
    print(f"  candidates {planning.candidate_seconds:.2f} s, selection {planning.selection_seconds:.2f} s"
          + (f", {len(planning.exchange_history) - 1} exchange swaps" if args.method == "exchange" else ""))
    print("  index       " + "  ".join(f"{name:>10}" for name in INDICES))
    print("  planned     " + "  ".join(f"{planning.indices[name]:>10.4g}" for name in INDICES))
    print("  random mean " + "  ".join(f"{random[name]:>10.4g}" for name in INDICES))
    error = planning.indices[PREDICTION]
    if weighted and math.isfinite(error):
        print(f"  predicted RMS position error over the workspace (linearised, noise-weighted fit): "
              f"{error * 1e6:.1f} um planned, {random[PREDICTION] * 1e6:.1f} um random")
    if planning.rank < N_PARAMETERS:
        print(f"  note: rank {planning.rank} of {N_PARAMETERS} with the {args.cost} cost, so every index is 0; the "
              "plan maximises log det(M + delta I), the information on the identifiable part")
    print(f"wrote {args.out}")
    return 0


def run_report(args) -> int:
    from .report import write_report

    page = write_report(args.result, args.out, title=args.title)
    print(f"wrote {page}")
    return 0
