"""Same bytes on every machine: the simulator and the labeller under other BLAS kernels and SIMD levels.

OpenBLAS picks its kernel by processor (or ``OPENBLAS_CORETYPE``), and numpy its SIMD loops by
processor (or ``NPY_DISABLE_CPU_FEATURES``). Kernels with and without fused multiply-add give
other last bits; before the products that feed written values were spelled out
(:mod:`ofbe_data.core.geometry`) and label floats rounded (:mod:`ofbe_data.core.precision`), a machine
whose kernel differs wrote other truth files and labels. Each variant here runs in its own
process, simulating two tiny campaigns (rotated: sync, Rodrigues labels, campaign fit;
multi-position: the pose fit) and labelling them; every file written must be byte-identical.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

CAMPAIGNS = ("tiny-rotated", "tiny-multi-position")
CORETYPES = ("Haswell", "Zen", "Nehalem", "Sandybridge")

_SCRIPT = """
import sys
from ofbe_data.cli.simulate import main as simulate
from ofbe_data.cli.label import main as label
out = sys.argv[1]
for c in sys.argv[2:]:
    assert simulate([c, "--out", f"{out}/raw/{c}", "--quiet"]) == 0
    assert label([f"{out}/raw/{c}", "--out", f"{out}/labels", "--min-samples", "1000", "--quiet"]) == 0
"""


def _simd_variants() -> list[str]:
    """``NPY_DISABLE_CPU_FEATURES`` values: for each SIMD level numpy dispatches to and finds on
    this processor, that level and every higher one disabled (numpy then runs one level lower)."""
    from numpy._core import _multiarray_umath as um

    found = [f for f in um.__cpu_dispatch__ if um.__cpu_features__.get(f) and f not in um.__cpu_baseline__]
    return [" ".join(found[i:]) for i in range(len(found))]


def _digest(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _run(out: Path, env_extra: dict[str, str]) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES")}
    env.update(env_extra)
    done = subprocess.run([sys.executable, "-c", _SCRIPT, str(out), *CAMPAIGNS], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, f"{env_extra}: {done.stderr[-2000:]}"
    return _digest(out)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, str]:
    files = _run(tmp_path_factory.mktemp("default"), {})
    assert any(k.endswith(".parquet") for k in files) and any("_truth" in k for k in files)
    return files


@pytest.mark.parametrize("env", [{"OPENBLAS_CORETYPE": c} for c in CORETYPES]
                         + [{"NPY_DISABLE_CPU_FEATURES": v} for v in _simd_variants()],
                         ids=lambda e: "-".join(f"{k}={v}" for k, v in e.items()).replace(" ", "+"))
def test_simulator_and_labeller_write_the_same_bytes(reference, env, tmp_path) -> None:
    got = _run(tmp_path, env)
    differ = sorted(k for k in reference if got.get(k) != reference[k])
    assert set(got) == set(reference)
    assert not differ, f"{env}: {len(differ)} files differ, e.g. {differ[:4]}"


def test_the_products_are_blas_free_and_exact() -> None:
    """mul3 equals BLAS to rounding and does not fuse: (a·b + c·d) + e·f in that order."""
    from ofbe_data.core.geometry import dot3, mul3, norm3

    rng = np.random.default_rng(5)
    a, m, v = rng.normal(size=(50, 3)), rng.normal(size=(3, 3)), rng.normal(size=3)
    np.testing.assert_allclose(mul3(a, m.T), a @ m.T, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(mul3(m, v), m @ v, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(mul3(v, m), v @ m, rtol=1e-14, atol=1e-15)
    assert float(norm3(v)) == pytest.approx(float(np.linalg.norm(v)), rel=1e-15)
    x, y = np.array([1.0 + 2**-30, 1.0, 1.0]), np.array([1.0 - 2**-30, -1.0, 2**-60])
    # with a fused multiply-add the first product would keep its −2**-60 term
    assert float(dot3(x, y)) == (1.0 - 1.0) + 2**-60
    with pytest.raises(ValueError, match="mul3 needs"):
        mul3(np.zeros((2, 4)), m)
