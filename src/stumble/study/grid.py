"""A study's grid: the scenarios to run, from the command line or a TOML file.

Every axis names one ``Scenario`` field (in the units of that field) and takes:

- one value: ``1.1``;
- a list: ``0.8,1.1,1.4`` (TOML: ``[0.8, 1.1, 1.4]`` or ``"0.8,1.1,1.4"``);
- a range of ``count`` evenly spaced values, both ends included: ``0.05:0.75:15``
  (TOML: ``"0.05:0.75:15"``).

``repeats = R`` runs every grid point with the seeds 1 … R (each seed perturbs the
initial state; see ``stumble.trip.perturb_initial_state``). An axis that is not
given takes the ``Scenario`` default. Every scenario of the grid is validated before
anything runs, so a bad value is one line naming it, never a failure half-way through.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import tomllib
from collections.abc import Iterator
from dataclasses import dataclass, field, fields
from pathlib import Path

from stumble.errors import InputError
from stumble.trip import OBSTACLE_HEIGHT_M, WALK_IN_S, Scenario, TripForce

CONTROLLERS = ("fsm", "reflex", "gh2010")
MAX_REPEATS = 100_000
MAX_RUNS = 10_000_000  # runs in one study: each is a row, its key is checked up front


@dataclass(frozen=True)
class Axis:
    """One grid axis: its name on the command line and in TOML, the Scenario field, the type."""

    name: str
    field: str
    kind: type
    help: str


# Outer to inner loop: axes that share a walk (body, speed, time step) are outermost, so
# the runs that reuse one cached walk (``stumble.gait.walk_cache.body_and_walk``) sit
# next to each other.
AXES: dict[str, Axis] = {a.name: a for a in (
    Axis("controller", "controller", str, "fsm (SCA 2009 state machines), reflex (seed 003's "
         "network) or gh2010 (Geyer & Herr 2010's reflexes)"),
    Axis("height", "height_m", float, "body height in m"),
    Axis("mass", "mass_kg", float, "body mass in kg"),
    Axis("sex", "sex", str, "male or female (de Leva 1996 parameter set)"),
    Axis("contact", "contact", str, "foot contact: lumped (default), points, penalty or soft"),
    Axis("timestep", "timestep_s", float,
         "physics time step in s (default: 0.002; a gh2010 set fitted at 1 ms needs a step "
         "that divides 1 ms)"),
    Axis("speed", "speed_m_per_s", float, "walking speed in m/s, 0.7-1.6"),
    Axis("mechanism", "mechanism", str, "force or obstacle"),
    Axis("obstacle_height", "obstacle_height_m", float,
         "obstacle height in m (obstacle trips only)"),
    Axis("leg", "leg", str, "tripped leg: left or right"),
    Axis("strategy", "strategy", str, "strategy mode: auto, elevating or lowering"),
    Axis("delay_scale", "delay_scale", float, "latencies multiplied by this (which: "
         "--delays)"),
    Axis("delays", "delays", str, "what --delay-scale multiplies: all (every delay: the "
         "reflex controllers' nerves and reflexes, the walk-in too; default) or response "
         "(the response to the trip's alone: the reflex controllers' touch response; for "
         "fsm the same)"),
    Axis("strength_scale", "strength_scale", float,
         "servo torque limits (fsm) or muscle F_max (reflex, gh2010) multiplied by this"),
    Axis("strength", "strength_model", str, "servo torque limits: fixed (default) or "
         "anderson2007 (human strength by joint angle and velocity)"),
    Axis("recovery", "recovery", str, "what recovered means (fsm): walk_on (still "
         "walking at the end of --duration, default) or step (1 s after the recovery "
         "step)"),
    Axis("population", "population", str, "young (default) or older (fsm): strength, "
         "response latencies, torque development"),
    Axis("duration", "duration_after_trip_s", float, "seconds of physics after the trip "
         "at most (default 6 for fsm walking on, else 3)"),
    Axis("start", "start", str, "playback (the recorded walk to the trip; default fsm) or "
         "own (the reflex controllers' own gait; their default)"),
    Axis("walk_in", "walk_in_s", float, "start own: seconds walked before the trip's swing "
         "(default 4)"),
    Axis("swing", "swing_fraction", float, "trip instant as a fraction of swing, 0.05-0.9"),
    Axis("seed", "seed", int, "0: the recorded walk; others perturb the initial state"),
)}
OTHER_KEYS = ("repeats", "description", "params")  # TOML keys that are not axes


@dataclass(frozen=True)
class Grid:
    """The axes given (name → values) and the repeats; everything else is the default."""

    axes: dict[str, list] = field(default_factory=dict)
    repeats: int | None = None
    params: str | None = None  # state-machine parameters (``--params``): a path or a name

    def values(self, name: str) -> list:
        """The values of axis ``name``: given, implied by repeats, or the default."""
        if name in self.axes:
            return list(self.axes[name])
        if name == "seed" and self.repeats:
            return list(range(1, self.repeats + 1))
        return [getattr(Scenario(), AXES[name].field)]

    def varying(self) -> list[str]:
        """Axes with more than one value, in loop order."""
        return [n for n in AXES if len(self.values(n)) > 1]

    def count(self) -> int:
        """How many runs the grid has, counted without building it (force trips once
        whatever the obstacle-height axis says)."""
        sizes = {n: len(self.values(n)) for n in AXES}
        rest = math.prod(v for n, v in sizes.items() if n not in ("mechanism",
                                                                   "obstacle_height"))
        mechs = self.values("mechanism")
        per = sum(1 if m == "force" else sizes["obstacle_height"] for m in mechs)
        return rest * per

    def checked_count(self) -> int:
        """``count()``, or InputError when it is more than ``MAX_RUNS`` or a value of an
        axis that ``normalised`` may drop is bad (``DROPPABLE``: checked here, since the
        runs where it cannot matter never see it)."""
        for name in DROPPABLE:
            for v in self.values(name):
                Scenario(**{AXES[name].field: v}).validated()
        n = self.count()
        if n > MAX_RUNS:
            raise InputError(f"the grid has {n:,} runs, more than the limit of {MAX_RUNS:,} "
                             "for one study (split it into several --out directories)")
        return n

    def iter_scenarios(self) -> Iterator[Scenario]:
        """Every scenario of the grid in loop order, one at a time, without duplicates.

        Force trips ignore the obstacle height, so over an obstacle-height axis a force
        trip is run once (at the default height; its row has no obstacle height), where
        the axis' first value stands. Not validated: see ``check_scenario``."""
        names = list(AXES)
        first_height = self.values("obstacle_height")[0]
        for combo in itertools.product(*(self.values(n) for n in names)):
            values = dict(zip(names, combo, strict=True))
            if values["mechanism"] == "force" and values["obstacle_height"] != first_height:
                continue
            yield normalised(Scenario(**{AXES[n].field: v for n, v in values.items()}))

    def scenarios(self) -> list[Scenario]:
        """Every scenario of the grid, validated, in loop order (small grids; a study
        streams them with ``iter_scenarios``)."""
        self.checked_count()
        scs = list(self.iter_scenarios())
        for sc in scs:
            check_scenario(sc)
        return scs

    def to_json(self) -> dict:
        """JSON-ready description: every axis with its values (defaults included)."""
        d = {n: self.values(n) for n in AXES}
        if self.repeats:
            d["repeats"] = self.repeats
        return d

    def merged(self, other: Grid) -> Grid:
        """This grid with ``other``'s axes (and repeats, params) replacing its own."""
        axes = {**self.axes, **other.axes}
        repeats = other.repeats if other.repeats is not None else self.repeats
        if "seed" in other.axes:
            repeats = None
        elif other.repeats is not None:
            axes.pop("seed", None)
        return Grid(axes, repeats, other.params if other.params is not None else self.params)


# the axes whose value ``normalised`` replaces by the default where it cannot matter
# (a force trip's obstacle height, a playback start's walk-in, the state machines'
# delays); each check of ``Scenario.validated`` on them holds whatever the other fields
DROPPABLE = ("obstacle_height", "walk_in", "delays")


def normalised(sc: Scenario) -> Scenario:
    """The scenario with the controller's defaults filled in (``Scenario.resolved``) and
    the fields that cannot matter set to their defaults."""
    sc = sc.resolved()
    if sc.controller == "fsm" and sc.delays != "all":  # every fsm delay is its response's
        sc = sc.with_(delays="all")
    if sc.mechanism == "force" and sc.obstacle_height_m != OBSTACLE_HEIGHT_M:
        sc = sc.with_(obstacle_height_m=OBSTACLE_HEIGHT_M)
    if sc.start != "own" and sc.walk_in_s != WALK_IN_S:
        sc = sc.with_(walk_in_s=WALK_IN_S)
    return sc


def check_scenario(sc: Scenario) -> None:
    """InputError naming the first bad field of a scenario (``Scenario.validated`` and more)."""
    from stumble.body.anthropometry import check_person
    from stumble.body.contact import check_mode

    if sc.controller not in CONTROLLERS:
        raise InputError(f"controller {sc.controller!r} is not one of {', '.join(CONTROLLERS)}")
    sc.validated()
    check_person(sc.height_m, sc.mass_kg, sc.sex)
    check_mode(sc.contact)


def _canonical(v):
    if isinstance(v, bool) or isinstance(v, str):
        return v
    if isinstance(v, int):
        return int(v)
    return round(float(v), 10)


def scenario_fields(sc: Scenario) -> dict:
    """The scenario as plain values (the controller's defaults filled in), ``force`` left
    out unless it differs from the default."""
    sc = sc.resolved()
    d = {f.name: _canonical(getattr(sc, f.name)) for f in fields(Scenario) if f.name != "force"}
    if sc.force != TripForce():
        d["force"] = {f.name: _canonical(getattr(sc.force, f.name)) for f in fields(TripForce)}
    return d


def run_key(sc: Scenario) -> str:
    """A stable 16-hex-digit key of a scenario: SHA-256 of its fields as canonical JSON.

    Same scenario, same key, on any machine and in any process; it does not depend on the
    stumble version (see the ``stumble_version`` column for that)."""
    d = scenario_fields(sc)
    if d["delays"] == "all":  # the default left out, so that the keys of the studies
        del d["delays"]  # made before the field (2026-12-05) stay theirs
    if d["mechanism"] == "obstacle":  # since 2026-12-07 an obstacle trip's recovery needs
        d["recovered_past_obstacle"] = True  # the body past the box: a study made before
        # re-runs those trips rather than keep their verdicts (analysis.StopRule.past_x)
    text = json.dumps(d, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# ---------------------------------------------------------------- parsing


def _scalar(axis: Axis, v, where: str):
    """One value of an axis, from text (command line) or a TOML scalar."""
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):  # a TOML date too
        raise InputError(f"{where}: {v!s} is not a value for {axis.name}")
    if axis.kind is str:
        if not isinstance(v, str) or not v.strip():
            raise InputError(f"{where}: {v!r} is not a name")
        return v.strip()
    if isinstance(v, str):
        text = v.strip()
        try:
            v = int(text) if axis.kind is int else float(text)
        except ValueError:
            what = "an integer" if axis.kind is int else "a number"
            raise InputError(f"{where}: {text!r} is not {what}") from None
    if axis.kind is int:
        if isinstance(v, float) and not v.is_integer():
            raise InputError(f"{where}: {v!r} is not an integer")
        return int(v)
    v = float(v)
    if not math.isfinite(v):
        raise InputError(f"{where}: {v!r} is not a finite number")
    return round(v, 10)


def _range(axis: Axis, text: str, where: str) -> list:
    """``start:stop:count``: count evenly spaced values, both ends included."""
    parts = [p.strip() for p in text.split(":")]
    if len(parts) != 3 or not all(parts):
        raise InputError(f"{where}: {text!r} is not a range start:stop:count "
                         "(e.g. 0.05:0.75:15)")
    if axis.kind is str:
        raise InputError(f"{where}: {axis.name} takes names, not a range")
    start = _scalar(Axis(axis.name, axis.field, float, ""), parts[0], where)
    stop = _scalar(Axis(axis.name, axis.field, float, ""), parts[1], where)
    try:
        count = int(parts[2])
    except ValueError:
        raise InputError(f"{where}: the count {parts[2]!r} of {text!r} is not an integer") from None
    if count < 1 or (count == 1 and start != stop):
        raise InputError(f"{where}: a range of {count} value(s) from {parts[0]} to {parts[1]} "
                         "makes no sense (count >= 2, or 1 when start = stop)")
    if count > MAX_REPEATS:
        raise InputError(f"{where}: {count} values in one range is more than {MAX_REPEATS}")
    step = 0.0 if count == 1 else (stop - start) / (count - 1)
    vals = [start + k * step for k in range(count)]
    vals[-1] = stop
    return [_scalar(axis, v, where) for v in vals]


def parse_values(axis_name: str, spec, where: str | None = None) -> list:
    """The values of one axis from a command-line string or a TOML value.

    ``where`` prefixes error messages (default ``--<axis>``). Duplicates are dropped,
    order kept.
    """
    axis = AXES[axis_name]
    where = where or f"--{axis_name.replace('_', '-')}"
    if isinstance(spec, list):
        if not spec:
            raise InputError(f"{where}: the list is empty")
        if any(isinstance(v, (list, dict)) for v in spec):
            raise InputError(f"{where}: a list of values may not nest")
        vals = [_scalar(axis, v, where) for v in spec]
    elif isinstance(spec, str) and ":" in spec:
        vals = _range(axis, spec, where)
    elif isinstance(spec, str) and "," in spec:
        items = [s.strip() for s in spec.split(",")]
        if not all(items):
            raise InputError(f"{where}: {spec!r} has an empty item")
        vals = [_scalar(axis, s, where) for s in items]
    elif isinstance(spec, dict):
        raise InputError(f"{where}: a table is not a value (use a number, a list or "
                         "\"start:stop:count\")")
    else:
        vals = [_scalar(axis, spec, where)]
    return list(dict.fromkeys(vals))


def _repeats(v, where: str) -> int:
    if isinstance(v, bool) or (isinstance(v, float) and not v.is_integer()):
        raise InputError(f"{where}: {v!r} is not a whole number")
    try:
        n = int(v)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {v!r} is not a whole number") from None
    if not 1 <= n <= MAX_REPEATS:
        raise InputError(f"{where}: {n} is outside 1-{MAX_REPEATS}")
    return n


def grid_from_mapping(d: dict, where: str, base_dir: Path | None = None) -> Grid:
    """A grid from a mapping of axis names to values (a parsed TOML file).

    Keys may use ``_`` or ``-`` (``obstacle_height`` or ``obstacle-height``). ``params``
    is a state-machine parameter file (a path, relative to ``base_dir``, the TOML file's
    directory) or a shipped set's name, as ``stumble study --params`` takes it."""
    axes: dict[str, list] = {}
    repeats = params = None
    for raw, v in d.items():
        key = raw.replace("-", "_")
        if key == "description":
            continue
        if key == "params":
            if not isinstance(v, str) or not v.strip():
                raise InputError(f"{where}: params must be a file name or a shipped set's "
                                 f"name (a string), got {v!r}")
            from stumble.control.fsm_params import SHIPPED

            params = (v if v in SHIPPED or base_dir is None or Path(v).is_absolute()
                      else str(base_dir / v))
            continue
        if key == "repeats":
            repeats = _repeats(v, f"{where}: repeats")
            continue
        if key not in AXES:
            known = ", ".join([*AXES, *OTHER_KEYS])
            raise InputError(f"{where}: unknown key {raw!r} (known: {known})")
        axes[key] = parse_values(key, v, f"{where}: {key}")
    if "seed" in axes and repeats:
        raise InputError(f"{where}: give seed or repeats, not both")
    return Grid(axes, repeats, params)


def load_toml(path: Path) -> Grid:
    """A grid from a TOML file: top-level keys are axes (and ``repeats``, ``description``)."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError(f"{path}: no such study file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: cannot be read ({e})") from None
    try:
        d = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path.name}: not valid TOML ({e})") from None
    if "grid" in d and isinstance(d["grid"], dict):  # a [grid] table is accepted too
        rest = {k: v for k, v in d.items() if k != "grid"}
        d = {**rest, **d["grid"]}
    return grid_from_mapping(d, path.name, path.parent)


def grid_from_args(specs: dict[str, str | None], repeats: int | None) -> Grid:
    """A grid from command-line strings (axis name → spec, None when not given)."""
    axes = {n: parse_values(n, s) for n, s in specs.items() if s is not None}
    if repeats is not None:
        repeats = _repeats(repeats, "--repeats")
        if "seed" in axes:
            raise InputError("--seed and --repeats: give one, not both")
    return Grid(axes, repeats)
