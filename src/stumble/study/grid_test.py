"""The grid: axis values from the command line or a TOML file, their errors, run keys."""

import subprocess
import sys
import textwrap

import pytest

from stumble.errors import InputError
from stumble.study.grid import Grid, load_toml, parse_values, run_key
from stumble.trip import Scenario


def test_values_ranges_lists_and_singles():
    swing = parse_values("swing", "0.05:0.75:15")
    assert len(swing) == 15 and swing[0] == 0.05 and swing[-1] == 0.75
    assert swing[1] == 0.1 and swing[2] == 0.15  # rounded: keys match typed values
    assert parse_values("speed", "0.8,1.1,1.4") == [0.8, 1.1, 1.4]
    assert parse_values("speed", "1.2") == [1.2]
    assert parse_values("seed", "0:4:5") == [0, 1, 2, 3, 4]
    assert parse_values("controller", "fsm, reflex") == ["fsm", "reflex"]
    assert parse_values("speed", [0.8, 1.1, 0.8]) == [0.8, 1.1]  # TOML list, duplicate
    assert parse_values("speed", "1.1:1.1:1") == [1.1]


@pytest.mark.parametrize("axis, spec, words", [
    ("swing", "0.05:0.75", "not a range start:stop:count"),
    ("swing", "a:0.7:3", "'a' is not a number"),
    ("swing", "0.1:0.5:x", "count 'x'"),
    ("swing", "0.1:0.5:1", "makes no sense"),
    ("speed", "1.1,,1.4", "empty item"),
    ("speed", "nan", "not a finite number"),
    ("seed", "0.5", "not an integer"),
    ("seed", "0:1:3", "not an integer"),
    ("strategy", "auto:lowering:2", "takes names, not a range"),
])
def test_value_errors_are_one_line(axis, spec, words):
    with pytest.raises(InputError) as e:
        parse_values(axis, spec)
    assert words in str(e.value) and "\n" not in str(e.value)
    assert str(e.value).startswith(f"--{axis}")


def test_toml_grid_and_its_errors(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(textwrap.dedent("""\
        description = "obstacle heights"
        swing = "0.1:0.7:4"
        speed = [1.0, 1.3]
        mechanism = ["force", "obstacle"]
        obstacle-height = [0.08, 0.14]
        repeats = 2
        """))
    g = load_toml(f)
    assert g.values("seed") == [1, 2] and g.varying() == [
        "speed", "mechanism", "obstacle_height", "swing", "seed"]
    scs = g.scenarios()
    # force trips ignore the obstacle height: 4 swings x 2 speeds x 2 seeds x (1 + 2)
    assert len(scs) == 4 * 2 * 2 * 3
    assert {s.obstacle_height_m for s in scs if s.mechanism == "force"} == {0.10}
    assert len({run_key(s) for s in scs}) == len(scs)
    # the command line replaces the file's axes
    g2 = g.merged(Grid({"speed": [1.2]}, None))
    assert g2.values("speed") == [1.2] and g2.values("swing") == g.values("swing")

    for text, words in [("swingg = 0.2", "unknown key 'swingg'"),
                        ("swing = 0.2\nspeed = [", "not valid TOML"),
                        ("swing = \"0.1:0.2\"", "swing: '0.1:0.2' is not a range"),
                        ("seed = [1]\nrepeats = 2", "seed or repeats, not both"),
                        ("speed = {a = 1}", "a table is not a value"),
                        ("repeats = 1.5", "not a whole number"),
                        # TOML dates and times are no axis values
                        ("swing = 1979-05-27", "swing: 1979-05-27 is not a value for swing"),
                        ("swing = [07:32:00]", "07:32:00 is not a value for swing"),
                        ("seed = 1979-05-27", "seed: 1979-05-27 is not a value for seed")]:
        f.write_text(text)
        with pytest.raises(InputError) as e:
            load_toml(f)
        assert words in str(e.value) and "\n" not in str(e.value), text
    with pytest.raises(InputError, match="no such study file"):
        load_toml(tmp_path / "missing.toml")


def test_run_keys_are_stable_and_distinct():
    a = Scenario(swing_fraction=parse_values("swing", "0.05:0.75:15")[2])
    b = Scenario(swing_fraction=0.15)
    assert run_key(a) == run_key(b) and len(run_key(a)) == 16
    assert run_key(b) != run_key(b.with_(seed=1))
    assert run_key(b) != run_key(b.with_(delay_scale=1.5))
    g = b.with_(controller="gh2010", mechanism="obstacle", delay_scale=1.5)
    assert run_key(g) != run_key(g.with_(delays="response"))
    # the default delays are left out of the key: a study made before the field
    # (2026-12-05) resumes (this scenario's key then, recorded)
    assert run_key(b) == "1b87e27aaa405adf"
    # every delay of the state machines is its response's: one scenario, one key
    from stumble.study.grid import normalised

    assert normalised(b.with_(delays="response")) == normalised(b)
    # the key is a pure function of the fields: the same in a fresh interpreter
    code = "from stumble.study.grid import run_key; from stumble.trip import Scenario; " \
           "print(run_key(Scenario(swing_fraction=0.15)))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == run_key(b)
