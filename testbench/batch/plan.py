"""What a Monte Carlo batch is: N runs of one scenario, each with its own seed sequence
(SeedSequence(seed).spawn(N)) and, optionally, parameters varied by distribution.

`--vary key=DIST` forms (values are drawn from the batch's own "vary" stream, so the same
batch gives the same draws):
  uniform(a, b) | normal(mu, sigma) | choice(a, b, c) | linspace(a, b)  (evenly over runs)
  | sequence(a, b, c)  (run i takes the i-th value, cycling: every value used as evenly as can be)
`key+=DIST` adds the draw to the scenario's own value (a dispersion about it), and several
comma-separated keys take one and the same draw, so that a geometry moves as a whole:
  --vary "vehicles.uav0.initial.east_m,vehicles.uav0.mission.params.center.east_m+=uniform(-1000, 1000)"
flies the same racetrack 0-1 km further east or west, start included.
With several keys, choice and sequence also take bracketed tuples, one value per key, so that
values that belong together are drawn together: each run of
  --vary "world.imagery,world.reference_map=sequence([procedural:farmland?seed=101&season=summer,
          procedural:farmland?seed=101&season=autumn], [procedural:farmland?seed=102&season=summer, ...])"
flies over its own world, with the reference map another season of that same world.
"""

from __future__ import annotations

import json
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from testbench.core.errors import InputError
from testbench.core.rng import run_seed_sequences

_DIST = re.compile(r"^\s*(uniform|normal|choice|linspace|sequence)\s*\((.*)\)\s*$")


@dataclass(frozen=True)
class Vary:
    """One varied key: dotted scenario path and its distribution."""

    key: str
    """One dotted path, or several separated by commas (all take the same draw)."""
    dist: str
    args: tuple[Any, ...]
    offset: bool = False
    """True: the draw is added to the scenario's value (`key+=DIST`)."""

    @classmethod
    def parse(cls, text: str) -> "Vary":
        if "=" not in text:
            raise InputError(f"--vary {text!r}: expected key.path=distribution(args), e.g. vehicles.uav0.initial.heading_deg=uniform(0, 360)")
        key, _, rhs = text.partition("=")
        offset = key.endswith("+")
        key = ",".join(k.strip() for k in (key[:-1] if offset else key).split(","))
        if not all(key.split(",")):
            raise InputError(f"--vary {text!r}: empty key path")
        m = _DIST.match(rhs)
        if not m:
            raise InputError(f"--vary {text!r}: unknown distribution {rhs.strip()!r}; expected uniform(a, b), normal(mu, sigma), choice(a, b, ...), linspace(a, b) or sequence(a, b, ...)")
        name, raw_args = m.group(1), m.group(2)
        args = tuple(_arg(a, text) for a in _split_top(raw_args, text) if a.strip())
        need = {"uniform": 2, "normal": 2, "linspace": 2}
        if name in need and len(args) != need[name]:
            raise InputError(f"--vary {text!r}: {name} takes {need[name]} arguments, got {len(args)}")
        if name in ("choice", "sequence") and not args:
            raise InputError(f"--vary {text!r}: {name} needs at least one value")
        n_keys = len(key.split(","))
        if any(isinstance(a, tuple) for a in args):
            if name not in ("choice", "sequence") or not all(isinstance(a, tuple) and len(a) == n_keys for a in args):
                raise InputError(f"--vary {text!r}: bracketed values give one value per key: "
                                 f"choice or sequence of [v1, ..., v{n_keys}] for the {n_keys} keys, every one of them")
        if name in ("uniform", "normal", "linspace") and not all(isinstance(a, (int, float)) for a in args):
            raise InputError(f"--vary {text!r}: {name} takes numbers")
        if name in ("uniform", "normal", "linspace"):
            if not all(np.isfinite(args)):
                raise InputError(f"--vary {text!r}: {name} takes finite numbers")
            if name == "uniform" and args[0] > args[1]:
                raise InputError(f"--vary {text!r}: uniform(a, b) needs a <= b (expected the low bound first)")
            if name == "normal" and args[1] < 0:
                raise InputError(f"--vary {text!r}: normal(mu, sigma) needs sigma >= 0")
        if offset and not all(isinstance(a, (int, float)) for a in args):
            raise InputError(f"--vary {text!r}: += adds numbers; choose among numbers")
        return cls(key, name, args, offset)

    def overrides(self, value: Any) -> tuple[str, ...]:
        """The --set items that give one run this draw (one per key)."""
        op = "+=" if self.offset else "="
        keys = self.key.split(",")
        values = value if isinstance(value, (tuple, list)) else [value] * len(keys)
        return tuple(f"{k}{op}{json.dumps(v)}" for k, v in zip(keys, values))

    def draw(self, n: int, rng: np.random.Generator) -> list[Any]:
        """n values, one per run, in run order."""
        a = self.args
        if self.dist == "uniform":
            return [float(x) for x in rng.uniform(a[0], a[1], n)]
        if self.dist == "normal":
            return [float(x) for x in rng.normal(a[0], a[1], n)]
        if self.dist == "linspace":
            return [float(x) for x in np.linspace(a[0], a[1], n)]
        if self.dist == "sequence":
            return [a[i % len(a)] for i in range(n)]
        idx = rng.integers(0, len(a), n)
        return [a[i] for i in idx]


def _split_top(text: str, whole: str) -> list[str]:
    """Split at the commas outside brackets."""
    out, depth, cur = [], 0, []
    for ch in text:
        if ch == "[":
            depth += 1
        elif ch == "]":
            depth -= 1
            if depth < 0:
                break
        if ch == "," and depth == 0:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    if depth != 0:
        raise InputError(f"--vary {whole!r}: unbalanced brackets")
    out.append("".join(cur))
    return out


def _arg(text: str, whole: str) -> Any:
    """One distribution argument: a scalar, or a bracketed tuple of scalars."""
    t = text.strip()
    if t.startswith("[") and t.endswith("]"):
        inner = _split_top(t[1:-1], whole)
        if any("[" in x for x in inner):
            raise InputError(f"--vary {whole!r}: tuples do not nest")
        return tuple(_scalar(x) for x in inner)
    return _scalar(t)


def _scalar(text: str) -> Any:
    t = text.strip().strip("'\"")
    for conv in (int, float):
        try:
            return conv(t)
        except ValueError:
            pass
    return t


@dataclass(frozen=True)
class RunSpec:
    """One run of a batch: its index, seed sequence (entropy + spawn key), overrides."""

    index: int
    entropy: int
    spawn_key: tuple[int, ...]
    overrides: tuple[str, ...]
    varied: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return f"run_{self.index:05d}"

    def seed_sequence(self) -> np.random.SeedSequence:
        return np.random.SeedSequence(entropy=self.entropy, spawn_key=self.spawn_key)


@dataclass(frozen=True)
class BatchPlan:
    """The whole batch; `identity()` is what a resumed batch must match."""

    scenario: str
    runs: int
    seed: int
    overrides: tuple[str, ...]
    vary: tuple[Vary, ...]

    def run_specs(self) -> list[RunSpec]:
        seqs = run_seed_sequences(self.seed, self.runs)
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(self.seed, spawn_key=(0x7661_7279,))))  # "vary"
        draws = [(v, v.draw(self.runs, rng)) for v in self.vary]
        specs = []
        for i, s in enumerate(seqs):
            varied: dict[str, Any] = {}
            for v, vals in draws:
                if isinstance(vals[i], tuple):  # one value per key: each recorded under its own key
                    varied.update(zip(v.key.split(","), vals[i]))
                else:
                    varied[v.key + ("+" if v.offset else "")] = vals[i]
            extra = tuple(o for v, vals in draws for o in v.overrides(vals[i]))
            specs.append(RunSpec(i, int(s.entropy), tuple(int(x) for x in s.spawn_key), self.overrides + extra, varied))
        return specs

    def identity(self) -> dict[str, Any]:
        return {
            "scenario": str(Path(self.scenario).resolve()),
            "runs": self.runs,
            "seed": self.seed,
            "overrides": list(self.overrides),
            "vary": [asdict(v) | {"args": list(v.args)} for v in self.vary],
        }
