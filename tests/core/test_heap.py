"""The C heap's release policy (testbench.core.heap): with it, a loop of large temporaries reuses
freed memory instead of faulting in fresh pages; a threshold the user set is left alone."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

import pytest

pytestmark = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                                reason="glibc's malloc thresholds: Linux with glibc only")

# Twelve 2 MB temporaries alive at once, then all freed, twenty times: the ray march's pattern.
# Prints whether the thresholds were set and the page faults the loop took (after a warm-up).
_CHURN = """
import resource, sys
import numpy as np
from testbench.core.heap import keep_freed_memory
applied = keep_freed_memory() if sys.argv[1] == "set" else False
def churn():
    arrays = [np.ones(250_000) for _ in range(12)]
    del arrays
churn()
f0 = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(20):
    churn()
print(applied, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - f0)
"""


def _churn(mode: str, **env: str) -> tuple[bool, int]:
    """(thresholds set, page faults) of the churn loop in a fresh interpreter."""
    clean = {k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"}
    out = subprocess.run([sys.executable, "-c", _CHURN, mode], env={**clean, "NUMPY_MADVISE_HUGEPAGE": "0", **env},
                         capture_output=True, text=True, check=True).stdout.split()
    return out[0] == "True", int(out[1])


def _faults_per_round_at_least() -> int:
    """Where the kernel backs every anonymous mapping with 2 MB pages (transparent huge pages
    "always"), a round's 24 MB may fault in a dozen pages instead of 6 000 4 kB ones."""
    try:
        with open("/sys/kernel/mm/transparent_hugepage/enabled") as f:
            return 5 if "[always]" in f.read() else 2000
    except OSError:
        return 2000


def test_freed_temporaries_are_reused_instead_of_faulted_in_again():
    applied, faults = _churn("set")
    default_applied, default_faults = _churn("default")
    assert applied and not default_applied
    # glibc's defaults hand the 24 MB back after each round and fault it in again (about 6 000
    # pages a round, 116 000 measured); kept, the loop touches no new page.
    assert default_faults > 20 * _faults_per_round_at_least()
    assert faults < 0.05 * default_faults


def test_a_threshold_the_user_set_is_left_alone():
    applied, faults = _churn("set", MALLOC_TRIM_THRESHOLD_="1000000")
    assert not applied and faults > 20 * _faults_per_round_at_least()
    assert not _churn("set", GLIBC_TUNABLES="glibc.malloc.trim_threshold=1000000")[0]
