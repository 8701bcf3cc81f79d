"""``gaitlog ranges``: range collection and a data-type proposal for every fixed-point variable of the on-line
step algorithm, over recordings, IPOL trials and simulated walks."""

from __future__ import annotations

import argparse

from gaitlog.host.commands._options import SEED, add_json_option, add_verbosity_options, print_json, verbosity, whole
from gaitlog.host.errors import UsageError

HELP = ("observed range, headroom, saturations and the smallest format of every fixed-point variable of the "
        "on-line step algorithm")
#: Shown under "examples:" by ``gaitlog ranges --help``.
EXAMPLES = (
    "gaitlog ranges walk.glimg",
    "gaitlog ranges ipol-lowerback-dev --simulate 20",
    "gaitlog ranges --simulate 2 --margin-bits 2 --json",
    "gaitlog ranges --simulate 2 --words wexc14-wexcc15",
)
#: ``--simulate`` at most (each walker takes a few seconds).
MAX_SIMULATED = 1000


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recordings", nargs="*", metavar="RECORDING",
                        help="logger recordings (memory image, raw dump, wire capture), IPOL trials (_lb.txt or "
                             ".json) or folders of IPOL trials")
    parser.add_argument("--simulate", type=whole(minimum=1, maximum=MAX_SIMULATED), metavar="N",
                        help=f"also N simulated walkers (1-{MAX_SIMULATED})")
    parser.add_argument("--seed", type=SEED, default=0, help="first simulated walker's seed (default 0)")
    parser.add_argument("--margin-bits", type=whole(minimum=0, maximum=16), default=1, metavar="B",
                        help="the proposed formats hold the observed range times 2^B (0-16, default 1)")
    parser.add_argument("--words", metavar="LABEL",
                        help="count saturations and headroom against narrower words, a --q-formats label of words "
                             "only (e.g. wexc14-wexcc15-lpint1; gaitlog sweep --list-dimensions): the values the "
                             "shipped run stores beyond them")
    add_json_option(parser, "the table")
    add_verbosity_options(parser)


def run(args: argparse.Namespace) -> int:
    from gaitlog.host.studies.ranges import collect_ranges, words_label

    if not args.recordings and not args.simulate:
        raise UsageError("give at least one RECORDING or --simulate N")
    try:
        words = words_label(args.words or "shipped")
    except ValueError as err:
        raise UsageError(f"--words: {err}") from None
    report = collect_ranges(args.recordings, n_simulated=args.simulate or 0, seed=args.seed,
                            margin_bits=args.margin_bits, words=words)
    if args.json:
        print_json(report.to_dict())
    elif verbosity(args) >= 0:
        print(report.format_table())
    return 0
