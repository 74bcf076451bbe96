"""``imubounds export RESULTS --format F -o FILE``: filter parameters from the noise terms."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from imubounds.cli._common import add_force_option


def register(sub: Any) -> None:
    from imubounds.export import FORMATS

    p = sub.add_parser(
        "export",
        help="write a filter's IMU noise file (Kalibr, OpenVINS, VINS, GTSAM, ROS)",
        description="Turn the noise terms of 'imubounds static' (RESULTS: its output folder or "
        "noise.json) into the IMU noise parameters a filter reads: kalibr (imu.yaml, "
        "continuous-time densities), openvins (kalibr_imu_chain.yaml), vins (acc_n, gyr_n, "
        "acc_w, gyr_w per sample), gtsam (PreintegrationCombinedParams covariances), ros "
        "(sensor_msgs/Imu covariances at the log's rate). Every number carries its unit and "
        "the continuous/discrete conversion in a comment. With --motion DIR (an 'imubounds "
        "dynamic' output of mode full) N and K are multiplied by each channel's in-motion "
        "factor F (motion.json).",
    )
    p.add_argument("results", help="'imubounds static' output folder or its noise.json")
    p.add_argument("--format", required=True, choices=FORMATS, help="the filter's format")
    p.add_argument(
        "--motion", metavar="DYNAMIC_DIR",
        help="'imubounds dynamic' output folder (or its motion.json): in-motion figures",
    )
    p.add_argument("-o", "--out", metavar="FILE", help="output file (default: stdout)")
    add_force_option(p)
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no summary (by default the values written are printed)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from imubounds.export import export_noise, written_values

    text = export_noise(Path(args.results), args.format, motion=args.motion)
    if args.out is None:
        sys.stdout.write(text)
        return 0
    from imubounds.io.outputs import output_file

    # the files read are inputs too (never overwritten): a folder's noise.json, motion.json
    inputs = [args.results, str(Path(args.results) / "noise.json")]
    if args.motion:
        inputs += [args.motion, str(Path(args.motion) / "motion.json")]
    with output_file(args.out, force=args.force, inputs=inputs) as tmp:
        tmp.write_text(text, encoding="utf-8")
    if not args.quiet:
        what = "in-motion" if args.motion else "stationary"
        print(f"wrote {args.out} ({args.format}, {what} figures; units and conversions in "
              "its comments):")
        for line in written_values(text):
            print(f"  {line}")
    return 0
