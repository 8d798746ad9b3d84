"""Where a run was made: the code, the numerical libraries and the CPU features they use.

Why: a run is bit-identical under its seed only for the same code, the same library builds
and the same CPU features. OpenBLAS (numpy's and scipy's BLAS, a DYNAMIC_ARCH build) and
OpenCV pick vectorised kernels by the CPU at run time, and numpy has its own AVX-512 versions of
sin, cos, exp and log; kernels for other CPUs round some last bits differently, and a
closed-loop run fed a different last bit flies another realisation of the same scenario: the
same statistics, not the same numbers (measured in the README, "Conventions and
determinism"). `environment()` is written to run.json so that two records that differ can
be told apart from a change of code; `numerics_differences` lists what two runs' environments
differ in that can change the numbers (`testbench compare` prints it).
"""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any, Mapping

# Distributions whose builds take part in a run's arithmetic (by their PyPI names).
_NUMERIC_PACKAGES = ("numpy", "scipy", "opencv-python-headless", "jsbsim", "filterpy", "control", "torch", "pyarrow",
                     "rasterio", "pyproj", "pygeomag")
# Environment variables that change which kernels or how many threads the libraries use.
_NUMERIC_ENV = ("NPY_DISABLE_CPU_FEATURES", "NPY_ENABLE_CPU_FEATURES", "OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS",
                "OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENCV_CPU_DISABLE")


def environment() -> dict[str, Any]:
    """{"testbench": {"version", "git_commit", "git_dirty"}, "python", "platform", "cpu",
    "cpu_simd_flags": [...], "packages": {name: version}, "numpy_simd": [...], "blas": str,
    "opencv_cpu_features": str, "env": {VAR: value}} of this process. Fields that cannot be
    read are None, never an error: a run must not fail for want of its provenance."""
    import numpy as np

    from testbench import __version__

    commit, dirty = _git_state(Path(__file__).resolve().parents[2])
    np_config, cpu = _numpy_config(np), _cpuinfo()
    packages = {}
    for name in _NUMERIC_PACKAGES:
        try:
            packages[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            packages[name] = None
    return {
        "testbench": {"version": __version__, "git_commit": commit, "git_dirty": dirty},
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "cpu": _cpu_model(cpu),
        "cpu_simd_flags": _cpu_simd_flags(cpu),
        "packages": packages,
        "numpy_simd": _numpy_simd(np_config),
        "blas": _blas(np_config),
        "opencv_cpu_features": _opencv_features(),
        "env": {k: os.environ[k] for k in _NUMERIC_ENV if k in os.environ},
    }


def numerics_differences(a: Mapping[str, Any] | None, b: Mapping[str, Any] | None) -> list[str]:
    """What two environments (as environment() returns, e.g. from two run.json files) differ in
    that can change a run's numbers: the code's commit (or uncommitted changes), a numerical
    package's version, the CPU (model and vector flags), numpy's or OpenCV's CPU features, the
    BLAS build, or the environment variables above. [] when nothing differs; ["environment not
    recorded"] when either is missing (runs made before run.json carried it)."""
    if not a or not b:
        return ["environment not recorded"]
    out = []
    ta, tb = a.get("testbench") or {}, b.get("testbench") or {}
    if ta.get("git_commit") != tb.get("git_commit"):
        out.append(f"code: commit {_short(ta.get('git_commit'))} / {_short(tb.get('git_commit'))}")
    elif ta.get("git_dirty") or tb.get("git_dirty"):
        out.append("code: uncommitted changes in " + " and ".join(
            n for n, t in (("the base", ta), ("the new", tb)) if t.get("git_dirty")))
    pa, pb = a.get("packages") or {}, b.get("packages") or {}
    for name in sorted(set(pa) | set(pb)):
        if pa.get(name) != pb.get(name):
            out.append(f"{name} {pa.get(name)} / {pb.get(name)}")
    # The CPU model too: OpenBLAS picks its kernels by it, beyond the flags.
    for key, label in (("cpu", "CPU"), ("cpu_simd_flags", "CPU SIMD flags"), ("numpy_simd", "numpy CPU features"),
                       ("blas", "BLAS"), ("opencv_cpu_features", "OpenCV CPU features"),
                       ("env", "environment variables")):
        if a.get(key) != b.get(key):
            out.append(f"{label}: {a.get(key)} / {b.get(key)}")
    return out


def _short(commit: str | None) -> str:
    return commit[:10] if commit else "unknown"


def _git_state(root: Path) -> tuple[str | None, bool | None]:
    """(commit, has uncommitted changes) of the checkout the package runs from, or (None, None)
    when it is not a git checkout (an installed wheel) or git is missing."""
    if not (root / ".git").exists():
        return None, None
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10, check=True).stdout.strip()
        status = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                                capture_output=True, text=True, timeout=10, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None, None
    return commit or None, bool(status.strip())


def _cpu_model(cpuinfo: dict[str, str]) -> str | None:
    """The CPU's model name (from /proc/cpuinfo's fields; elsewhere platform.processor()), or None."""
    return cpuinfo.get("model name") or platform.processor() or None


def _cpu_simd_flags(cpuinfo: dict[str, str]) -> list[str] | None:
    """The CPU's vector-instruction flags (Linux /proc/cpuinfo: sse4_2, avx, avx2, fma,
    avx512*), the ones the libraries' kernel choice turns on."""
    flags = cpuinfo.get("flags")
    return None if flags is None else sorted(f for f in flags.split() if f.startswith(("sse4", "avx", "fma", "f16c")))


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields of /proc/cpuinfo ({} where there is none)."""
    info: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if not line.strip():
                    break  # the end of the first processor's block
                key, _, value = line.partition(":")
                info.setdefault(key.strip(), value.strip())
    except OSError:
        pass
    return info


def _numpy_config(np) -> dict:
    """numpy's build and run-time configuration (np.show_config's dictionary; {} if absent)."""
    try:
        return np.show_config(mode="dicts") or {}
    except Exception:  # noqa: BLE001 -- the layout of show_config is not a stable API
        return {}


def _numpy_simd(config: dict) -> list[str] | None:
    """The CPU feature groups numpy dispatches to on this machine (its build's "found" list)."""
    found = config.get("SIMD Extensions", {}).get("found")
    return None if found is None else list(found)


def _blas(config: dict) -> str | None:
    blas = config.get("Build Dependencies", {}).get("blas")
    return None if not blas else f"{blas.get('name')} {blas.get('version')}"


def _opencv_features() -> str | None:
    """OpenCV's CPU features line: the ones it was built for, '*' marking those it dispatches
    to at run time and '?' those this CPU lacks."""
    try:
        import cv2

        return cv2.getCPUFeaturesLine()
    except Exception:  # noqa: BLE001
        return None


__all__ = ["environment", "numerics_differences"]
