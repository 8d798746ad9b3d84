"""`testbench aircraft modes|list` end to end."""

from __future__ import annotations

import json

from testbench.commands import aircraft as aircraft_cmd


def _main(argv):
    import argparse

    parser = argparse.ArgumentParser()
    aircraft_cmd.register(parser.add_subparsers())
    args = parser.parse_args(argv)
    return args.handler(args)


def test_modes_command_prints_and_writes_json(tmp_path, capsys):
    out = tmp_path / "modes.json"
    assert _main(["aircraft", "modes", "tb_fixedwing", "--airspeed", "25", "--altitude", "1000", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    for name in ("short_period", "phugoid", "roll", "spiral", "dutch_roll"):
        assert name in text
    d = json.loads(out.read_text())
    assert d["trim"]["aircraft"] == "tb_fixedwing" and len(d["modes"]) == 5


def test_unknown_aircraft_exits_2_with_one_line():
    from testbench.cli import main

    assert main(["aircraft", "modes", "nope", "--airspeed", "25", "--altitude", "1000"]) == 2


def test_list_names_project_and_bundled_models(capsys):
    assert _main(["aircraft", "list"]) == 0
    text = capsys.readouterr().out
    assert "tb_fixedwing" in text and "tb_quad" in text and "c172x" in text


def test_design_command_reproduces_the_stored_gains(tmp_path, capsys):
    """`testbench aircraft design` prints a gains.py entry whose numbers are the stored set's."""
    import re

    from testbench.control.gains import DEFAULT_GAINS

    out = tmp_path / "design.json"
    assert _main(["aircraft", "design", "tb_fixedwing", "--airspeed", "25", "--altitude", "800", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("DEFAULT_GAINS['tb_fixedwing'] = FixedWingGains(")
    stored = DEFAULT_GAINS["tb_fixedwing"]
    for name in ("k_phi", "k_p", "k_r"):
        printed = float(re.search(rf"\b{name}=([-+0-9.e]+)", text).group(1))
        assert abs(printed - getattr(stored, name)) <= 1e-3 * max(1e-3, abs(getattr(stored, name)))  # as test_design
    d = json.loads(out.read_text())
    assert d["lat_min_damping"] > 0 and d["lon_min_damping"] > 0 and d["trim"]
