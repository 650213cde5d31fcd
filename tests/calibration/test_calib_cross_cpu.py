"""The same study, bit for bit, whatever CPU computes it (issue 71), shown on this machine by
making it compute as other CPUs do, each run in its own process: OpenBLAS's kernels for other
CPUs (``OPENBLAS_CORETYPE`` Haswell, SkylakeX, Zen, Sandybridge) with numpy's loops for what
each has (``NPY_DISABLE_CPU_FEATURES``: no AVX-512, or neither AVX-512 nor AVX2), and numba
compiling for a generic x86-64 CPU and for this one (``NUMBA_CPU_NAME``, each in its own
cache). Each factor alone was checked the same way when the numerics were made portable. The
study is the quick case, small (60 samples, three stages after the prior's): stage 0 from the
prior, the waste-free moves with the surrogate, its local systems and the population jumps, the
proposal covariance and its Cholesky factor, the weights and the evidence.

What is not covered (docs/layers.md): CPUs without FMA, on which glibc's exp and log take other
code paths (GLIBC_TUNABLES=glibc.cpu.hwcaps=-FMA changes the bits here).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from services.cli.results import results_stages
from services.stages import stage_states

ROOT = Path(__file__).resolve().parents[2]
NO_AVX512 = "X86_V4,AVX512_ICL,AVX512_SPR"

pytestmark = pytest.mark.slow

#: name -> environment; the generic variant compiles into a cache of its own, the host variant
#: and the others run on the test session's cache, which numba fills for this CPU (BLAS and
#: numpy do not change numba's machine code; compiled once, not once more for this test). Each
#: of the others is a CPU's profile: OpenBLAS's kernels for it with numpy's loops for what it
#: has (Haswell and Zen 2/3: AVX2 without AVX-512; Sandybridge: neither).
NUMBA = {"numba generic": {"NUMBA_CPU_NAME": "generic"}, "numba host": {"NUMBA_CPU_NAME": "host"}}
OTHERS = {
    "Haswell-like": {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": NO_AVX512},
    "Zen-like": {"OPENBLAS_CORETYPE": "Zen", "NPY_DISABLE_CPU_FEATURES": NO_AVX512},
    "Sandybridge-like": {
        "OPENBLAS_CORETYPE": "Sandybridge",
        "NPY_DISABLE_CPU_FEATURES": "X86_V3," + NO_AVX512,
    },
    "SkylakeX kernels": {"OPENBLAS_CORETYPE": "SkylakeX"},
}
#: instructions a profile's code needs from the CPU that runs the test: OpenBLAS's SkylakeX
#: kernels are AVX-512 code, an illegal instruction (SIGILL) on a CPU without it (the AMD EPYC
#: CI and this machine get on some days); there the profile is left out, and this CPU's own
#: kernels are the AVX2 ones the Haswell- and Zen-like profiles compare
NEEDS = {"SkylakeX kernels": "avx512f"}


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    return {f for line in text.splitlines() if line.startswith("flags") for f in line.split()}


def _runnable(profiles: dict[str, dict[str, str]]) -> dict[str, dict[str, str]]:
    flags = _cpu_flags()
    return {name: env for name, env in profiles.items() if NEEDS.get(name, "") in flags | {""}}


def _study(out: Path, env: dict[str, str], cache: Path | None) -> dict[str, dict]:
    """The stages of the small study run under ``env`` (wall times left out), its numba code in
    ``cache`` (None: the test session's)."""
    run_env = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    if cache is not None:
        run_env["NUMBA_CACHE_DIR"] = str(cache)
    cmd = [sys.executable, "-m", "services.cli", "calibrate", str(ROOT / "examples" / "quick.toml"),
           "--samples", "60", "--max-stages", "3", "--no-plots", "--quiet", "--workers", "1",
           "--out", str(out)]  # fmt: skip
    proc = subprocess.run(cmd, env=run_env, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, (env, proc.stderr[-2000:])
    summary = json.loads((out / "summary.json").read_text())
    with results_stages(out, summary) as kept:
        stages = {f"stage {s.stage}": s.to_dict() for s in stage_states(kept)}
    assert len(stages) == 4
    return stages


def test_the_same_study_is_bit_identical_as_other_cpus_compute_it(tmp_path: Path) -> None:
    others = _runnable(OTHERS)
    caches = {"numba generic": tmp_path / "cache_generic"}
    profiles = {**NUMBA, **others}
    with ThreadPoolExecutor(max_workers=2) as pool:  # the generic compile first, beside the rest
        futures = {
            name: pool.submit(_study, tmp_path / name.replace(" ", "_"), env, caches.get(name))
            for name, env in profiles.items()
        }
        runs = {name: future.result() for name, future in futures.items()}
    print(f"profiles run: {sorted(runs)}; left out (this CPU lacks what they need): "
          f"{sorted(OTHERS.keys() - others.keys())}")  # fmt: skip
    reference = runs["numba host"]
    log_z = reference["stage 3"]["log_evidence"]
    differ = [name for name, stages in runs.items() if stages != reference]
    assert not differ, f"{differ} differ from this CPU's run (log Z {log_z!r})"
