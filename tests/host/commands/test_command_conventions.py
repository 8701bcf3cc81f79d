"""What every ``gaitlog`` command shares: -q/-v, the one anatomy rule (flags, K file, an IPOL trial's height, a
1.70 m adult), progress callbacks of the long runs."""

from __future__ import annotations

import argparse
import json

import pytest

from gaitlog.host.cli import build_parser, main
from gaitlog.host.errors import HostError
from gaitlog.host.gait.anthropometry import choose_lengths


def _leaf_commands() -> list[tuple[str, argparse.ArgumentParser]]:
    """Every runnable command (``device status`` etc. for commands with actions), from the parser itself."""
    def walk(name: str, parser: argparse.ArgumentParser):
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if not subs:
            return [(name, parser)]
        return [leaf for n, p in subs[0].choices.items() for leaf in walk(f"{name} {n}".strip(), p)]

    return walk("", build_parser())


def test_every_command_has_quiet_and_verbose() -> None:
    leaves = _leaf_commands()
    assert len(leaves) >= 14                        # the parser was really walked
    for name, parser in leaves:
        by_flag = {o: a for a in parser._actions for o in a.option_strings}
        assert {"-q", "--quiet", "-v", "--verbose"} <= by_flag.keys(), name
        quiet, verbose = by_flag["-q"], by_flag["-v"]
        assert by_flag["--quiet"] is quiet and by_flag["--verbose"] is verbose, name
        # the meaning gaitlog.host.commands._options.verbosity reads: quiet a flag, verbose a count
        assert (quiet.dest, quiet.const, quiet.default) == ("quiet", True, False), name
        assert isinstance(verbose, argparse._CountAction) and (verbose.dest, verbose.default) == ("verbose", 0), name


# ----------------------------------------------------------------------------------------------- anatomy
# Winter's leg = 0.530 H; the paper's foot (heel to first metatarsal head) = 0.73 x Winter's 0.152 H
LEG_PER_H, FOOT_PER_H = 0.530, 0.73 * 0.152


def test_lengths_come_from_the_flags_first() -> None:
    c = choose_lengths(leg_length_m=0.9, foot_length_m=0.2, k_lengths_m=(0.8, 0.18), trial_height_m=1.6)
    assert (c.leg_length_m, c.foot_length_m, c.note, c.assumed) == (0.9, 0.2, "", False)
    c = choose_lengths(height_m=1.80, k_lengths_m=(0.8, 0.18), trial_height_m=1.6)
    assert c.leg_length_m == pytest.approx(LEG_PER_H * 1.80, abs=1e-6)
    assert c.foot_length_m == pytest.approx(FOOT_PER_H * 1.80, abs=1e-4) and not c.assumed


def test_then_the_k_file_then_the_trial_height_then_an_assumed_adult() -> None:
    c = choose_lengths(k_lengths_m=(0.8, 0.18), k_source="k.json", trial_height_m=1.6)
    assert (c.leg_length_m, c.foot_length_m, c.assumed) == (0.8, 0.18, False) and "k.json" in c.note
    c = choose_lengths(foot_length_m=0.2, k_lengths_m=(0.8, 0.18))
    assert (c.leg_length_m, c.foot_length_m) == (0.8, 0.2) and c.note.startswith("leg length from")
    c = choose_lengths(trial_height_m=1.6, trial_source="7-1.json")
    assert c.leg_length_m == pytest.approx(LEG_PER_H * 1.6, abs=1e-6) and not c.assumed
    assert "1.60 m" in c.note and "7-1.json" in c.note
    c = choose_lengths()
    assert c.assumed and c.leg_length_m == pytest.approx(LEG_PER_H * 1.70, abs=1e-6) and "1.70 m adult" in c.note
    with pytest.raises(HostError, match="height 175.0 m is outside"):
        choose_lengths(height_m=175.0)
    with pytest.raises(HostError, match="leg length 9.0 m"):
        choose_lengths(leg_length_m=9.0, k_lengths_m=(0.8, 0.18))


def test_estimate_takes_the_height_of_an_ipol_trial_and_says_so(shared_data, capsys) -> None:
    lb = shared_data / "ipol-lowerback-dev" / "GaitData" / "2-1_lb.txt"
    height_m = json.loads(lb.with_name("2-1.json").read_text())["Height"] / 100.0       # the JSON is in cm
    assert main(["estimate", str(lb), "--json"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert doc["leg_length_m"] == pytest.approx(LEG_PER_H * height_m, abs=1e-6)
    assert doc["foot_length_m"] == pytest.approx(FOOT_PER_H * height_m, abs=1e-4)
    assert f"{height_m:.2f} m" in doc["lengths_from"] and "2-1.json" in doc["lengths_from"]
    assert "1.70 m adult" not in captured.err
    # a flag wins over the trial's height
    assert main(["estimate", str(lb), "--json", "--height", "1.90"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["leg_length_m"] == pytest.approx(LEG_PER_H * 1.90, abs=1e-6) and doc["lengths_from"] == ""


def test_calibrate_k_refuses_trials_of_subjects_of_different_heights(shared_data, tmp_path) -> None:
    folder = shared_data / "ipol-lowerback-dev" / "GaitData"
    heights = {p.stem: json.loads(p.read_text()).get("Height") for p in sorted(folder.glob("*-1.json"))}
    other = next(n for n, h in heights.items() if h is not None and h != heights["1-1"])
    inputs = [str(folder / f"{n}_lb.txt") for n in ("1-1", other)]
    out = tmp_path / "k.json"
    with pytest.raises(HostError, match="different heights"):
        main_raise(["calibrate-k", *inputs, "--distance", "20", "--out", str(out)])
    assert not out.exists()


def main_raise(argv: list[str]) -> None:
    """Run a command's ``run`` directly, so its HostError reaches the test (main turns it into exit 1)."""
    args = build_parser().parse_args(argv)
    args._run(args)


# ---------------------------------------------------------------------------------------------- progress
def test_compare_simulate_ticks_once_per_subject(monkeypatch) -> None:
    from gaitlog.host.studies import simulation

    monkeypatch.setattr(simulation, "_compared_subject", lambda job: job[1])     # the subject's seed, no simulation
    ticks = []
    assert simulation.simulate_comparisons(3, seed=1, progress=lambda: ticks.append(1)) == [1000, 1001, 1002]
    assert len(ticks) == 3


# ---------------------------------------------------------------------------------- usage, suggestions, notices
@pytest.mark.parametrize(("argv", "hint"), [(["decod"], "did you mean 'decode'?"),
                                            (["estimat", "x"], "did you mean 'estimate'?"),
                                            (["device", "stauts"], "did you mean 'status'?")])
def test_a_mistyped_command_exits_2_and_suggests_the_right_one(argv, hint, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and hint in err and len(err.strip().splitlines()) == 1


def test_a_bad_option_value_a_command_finds_exits_2(tmp_path, capsys) -> None:
    # found by the command, not the parser (UsageError): still a usage error
    assert main(["compare", "--simulate", "1", str(tmp_path / "x.npz")]) == 2
    err = capsys.readouterr().err
    assert "give exactly one of" in err and "(usage: gaitlog compare --help)" in err


def test_one_adc_bits_limit_stated_where_the_logger_stores_the_codes(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["evaluate", "ipol", "x", "--adc-bits", "12"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "1..10" in err and "compare --simulate, sweep" in err
    args = build_parser().parse_args(["compare", "--simulate", "1", "--adc-bits", "12"])
    assert args.adc_bits == 12


@pytest.mark.parametrize("quiet", [False, True])
def test_a_compilation_is_announced_once_on_stderr(quiet, capsys) -> None:
    from gaitlog.firmware_sim.compiled import announce_compile, compile_listeners
    from gaitlog.host.cli import _compile_notice

    before = list(compile_listeners)
    with _compile_notice(argparse.Namespace(quiet=quiet)):
        announce_compile("numba compiles the firmware's code into /tmp/x")
        announce_compile("the on-line step kernel is compiled ahead of time into /tmp/y")
    assert compile_listeners == before
    err = capsys.readouterr().err.splitlines()
    assert err == ([] if quiet else ["gaitlog: compiling once for this version (numba compiles the firmware's code "
                                     "into /tmp/x); this takes about 30 s"])


def test_every_command_shows_examples_in_its_help() -> None:
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert "examples:" in parser.format_help()
    missing = [name for name, p in subs.choices.items() if "examples:\n  gaitlog " + name not in p.format_help()]
    assert not missing, f"commands without examples in --help (EXAMPLES in their module): {missing}"


# ----------------------------------------------------------------------------------------- --out and --force
def test_out_is_a_file_prefix_or_a_folder_with_or_without_a_slash(tmp_path, capsys) -> None:
    image = tmp_path / "walk.glimg"
    assert main(["record", "--motion", "poses", "--steps", "off", "--out", str(image), "-q"]) == 0
    (tmp_path / "outdir").mkdir()
    assert main(["decode", str(image), "--out", str(tmp_path / "outdir"), "-q"]) == 0     # an existing folder
    assert {p.name for p in (tmp_path / "outdir").iterdir()} == {"walk.npz", "walk.csv"}
    assert not (tmp_path / "outdir.csv").exists()
    (tmp_path / "slash").mkdir()
    assert main(["decode", str(image), "--out", f"{tmp_path / 'slash'}/", "-q"]) == 0      # a trailing slash
    assert {p.name for p in (tmp_path / "slash").iterdir()} == {"walk.npz", "walk.csv"}
    assert main(["decode", str(image), "--out", str(tmp_path / "w"), "-q"]) == 0            # a prefix
    assert (tmp_path / "w.npz").is_file() and (tmp_path / "w.csv").is_file()
    # a slash names a folder, which must exist: nothing is guessed
    assert main(["decode", str(image), "--out", f"{tmp_path / 'nofolder'}/", "-q"]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_an_existing_output_is_overwritten_only_with_force(tmp_path, capsys) -> None:
    image = tmp_path / "p.glimg"
    assert main(["record", "--motion", "poses", "--steps", "off", "--out", str(image), "-q"]) == 0
    first = image.read_bytes()
    assert main(["record", "--motion", "poses", "--steps", "off", "--seed", "3", "--out", str(image), "-q"]) == 1
    assert "exists; give --force to overwrite it" in capsys.readouterr().err and image.read_bytes() == first
    assert main(["record", "--motion", "poses", "--steps", "off", "--seed", "3", "--out", str(image), "-q",
                 "--force"]) == 0
    assert image.read_bytes() != first


def test_quiet_prints_errors_only_and_verbose_adds_detail(tmp_path, capsys) -> None:
    image = tmp_path / "w.glimg"
    assert main(["record", "--motion", "walk", "--out", str(image), "-q"]) == 0      # no height: a warning
    assert capsys.readouterr() == ("", "")
    assert main(["record", "--motion", "walk", "--out", str(image), "--force"]) == 0
    plain = capsys.readouterr()
    assert "warning" in plain.err and "header:" not in plain.out
    assert main(["record", "--motion", "walk", "--out", str(image), "--force", "-v"]) == 0
    assert "header: device" in capsys.readouterr().out
    assert main(["estimate", str(image), "--height", "1.75", "-q"]) == 0
    assert capsys.readouterr() == ("", "")
    assert main(["estimate", str(image), "--height", "1.75"]) == 0
    assert "events:" not in capsys.readouterr().out
    assert main(["estimate", str(image), "--height", "1.75", "-v"]) == 0
    assert "events: steps" in capsys.readouterr().out
