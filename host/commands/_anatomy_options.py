"""``--leg-length``, ``--foot-length`` and ``--height`` of the gait commands (not a command: the underscore keeps it
out of ``--help``)."""

from __future__ import annotations

import argparse


def add_anatomy_options(parser: argparse.ArgumentParser) -> None:
    """--leg-length / --foot-length / --height."""
    parser.add_argument("--leg-length", type=float, metavar="M", help="leg length (greater trochanter to floor), m")
    parser.add_argument("--foot-length", type=float, metavar="M",
                        help="foot length heel to first metatarsal head (M3's S2), m")
    parser.add_argument("--height", type=float, metavar="M",
                        help="body height, m: leg = 0.530 H, foot = 0.111 H when not given (Winter; ANSUR)")
