"""Per-file SHA-256 lists of the data stages (issue 24): what they hold, and that the numbers
the simulator and the labeller write do not depend on the CPU's vector width or BLAS kernel."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

from ofbe_data.core.checksums import sha256_list, write_sha256_list

ROOT = Path(__file__).resolve().parents[1]


def test_the_list_names_every_file_with_its_hash(tmp_path: Path) -> None:
    (tmp_path / "raw" / "c" / "s1").mkdir(parents=True)
    (tmp_path / "raw" / "c" / "s1" / "b.csv").write_bytes(b"1,2,3\n")
    (tmp_path / "raw" / "c" / "a.json").write_bytes(b"{}")
    (tmp_path / "other.txt").write_bytes(b"x")
    path = write_sha256_list(tmp_path / "checksums" / "simulate.sha256",
                             [tmp_path / "raw", tmp_path / "other.txt"], base=tmp_path)
    lines = path.read_text().splitlines()
    digest = {data: hashlib.sha256(data).hexdigest() for data in (b"x", b"{}", b"1,2,3\n")}
    assert lines == [f"{digest[b'x']}  other.txt", f"{digest[b'{}']}  raw/c/a.json",
                     f"{digest[b'1,2,3' + bytes([10])]}  raw/c/s1/b.csv"]
    assert sha256_list([tmp_path / "missing"], base=tmp_path) == b""
    checked = subprocess.run(["sha256sum", "-c", str(path)], cwd=tmp_path, capture_output=True, text=True)
    assert checked.returncode == 0, checked.stdout + checked.stderr  # the format sha256sum reads


def test_every_data_stage_writes_its_list_as_an_uncached_output() -> None:
    import yaml

    stages = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]
    for stage in ("simulate", "label", "datasets"):
        outs = stages[stage]["outs"]
        assert {f"checksums/{stage}.sha256": {"cache": False}} in outs, (stage, outs)
        text = (ROOT / "pipelines" / f"{stage}.py").read_text()
        assert f'CHECKSUMS = Path("checksums") / "{stage}.sha256"' in text
        assert "write_sha256_list(CHECKSUMS" in text


SCRIPT = """
import sys
from pathlib import Path
from ofbe_data.core.checksums import sha256_list
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import load_config, simulate_campaign
for name, profile, seed in (("ga", "tiny-gravity-aligned", 1), ("rot", "tiny-rotated", 2),
                            ("mpc", "tiny-multi-position-continuous", 3)):
    simulate_campaign(load_config(profile), Path("raw") / name, seed=seed, jobs=1, progress=False)
out = label_sessions(expand_sessions([Path("raw") / n for n in ("ga", "rot", "mpc")]),
                     LabelParams(min_samples=1000), Path("labels"), jobs=1, progress=False)
assert not [o.error for o in out if o.error]
sys.stdout.buffer.write(sha256_list(["raw", "labels"]))
"""


def _lists(tmp_path: Path, name: str, env: dict[str, str]) -> str:
    folder = tmp_path / name
    folder.mkdir()
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=folder, capture_output=True, text=True,
                          env={**os.environ, **env, "PYTHONPATH": str(ROOT)}, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_same_bytes_whatever_the_simd_width_or_blas_kernel(tmp_path: Path) -> None:
    """The tiny campaigns and their labels, simulated and labelled with numpy's SIMD dispatch
    narrowed to AVX2 (no AVX-512 kernels) and with OpenBLAS told it runs on a Haswell: the
    same SHA-256 of every file as the default (issue 24)."""
    default = _lists(tmp_path, "default", {})
    assert default.count("\n") > 50
    narrowed = _lists(tmp_path, "narrowed", {"NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"})
    haswell = _lists(tmp_path, "haswell", {"OPENBLAS_CORETYPE": "Haswell"})
    assert narrowed == default
    assert haswell == default


def test_names_with_a_newline_or_a_backslash_are_escaped_as_sha256sum_reads_them(tmp_path: Path) -> None:
    """GNU coreutils' own escaping: a raw file named with a newline cannot break the list."""
    (tmp_path / "raw").mkdir()
    for name in ("a\nb.csv", "c\\d.csv", "plain.csv"):
        (tmp_path / "raw" / name).write_bytes(name.encode())
    path = write_sha256_list(tmp_path / "list.sha256", [tmp_path / "raw"], base=tmp_path)
    lines = path.read_text().split("\n")
    assert len(lines) == 4 and lines[-1] == ""  # three files, three lines
    assert lines[0].startswith("\\") and lines[0].endswith("  raw/a\\nb.csv")
    assert lines[2].endswith("  raw/plain.csv") and not lines[2].startswith("\\")
    checked = subprocess.run(["sha256sum", "-c", str(path)], cwd=tmp_path, capture_output=True, text=True)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    (tmp_path / "raw" / "a\nb.csv").write_bytes(b"changed")
    checked = subprocess.run(["sha256sum", "-c", str(path)], cwd=tmp_path, capture_output=True, text=True)
    assert checked.returncode == 1 and "FAILED" in checked.stdout
