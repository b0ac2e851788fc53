"""The session's shared campaigns (tests/helpers/campaigns.py): built once whoever asks first, the
same folder for every later caller, and a campaign a test wrote into is refused."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.helpers.campaigns import SharedCampaignChanged, shared_campaign, tree_digest
from tests.helpers.paths import ROOT


class _Factory:
    """A stand-in for pytest's tmp_path_factory whose base folder is ``base``."""

    def __init__(self, base: Path) -> None:
        self.base = base

    def getbasetemp(self) -> Path:
        return self.base


def test_a_campaign_is_built_once_and_its_folder_is_returned_again(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    builds: list[Path] = []

    def build(folder: Path) -> None:
        builds.append(folder)
        (folder / "a").mkdir()
        (folder / "a" / "x.csv").write_text("1,2,3\n")

    first = shared_campaign(_Factory(tmp_path), "c", build)  # type: ignore[arg-type]
    again = shared_campaign(_Factory(tmp_path), "c", build)  # type: ignore[arg-type]
    assert first == again == tmp_path / "shared-campaigns" / "c" and len(builds) == 1
    assert (first / "a" / "x.csv").read_text() == "1,2,3\n"
    assert not (tmp_path / "shared-campaigns" / "c.partial").exists()


def test_a_campaign_a_test_wrote_into_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    factory = _Factory(tmp_path)
    folder = shared_campaign(factory, "c", lambda f: (f / "x.csv").write_text("1\n"))  # type: ignore[arg-type]
    before = tree_digest(folder)
    (folder / "out").mkdir()
    (folder / "out" / "y.json").write_text("{}")
    assert tree_digest(folder) != before
    with pytest.raises(SharedCampaignChanged, match="a test wrote into a shared campaign"):
        shared_campaign(factory, "c", lambda f: None)  # type: ignore[arg-type]


def test_workers_asking_at_once_build_it_once(tmp_path: Path) -> None:
    """Four processes, as pytest-xdist's workers (each with its own base below a shared parent),
    ask for the same campaign at once: one builds, all get the same folder."""
    code = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        sys.path.insert(0, {str(ROOT)!r})
        from tests.helpers.campaigns import shared_campaign

        class F:
            def getbasetemp(self):
                return Path({str(tmp_path)!r}) / sys.argv[1]

        def build(folder):
            with open(Path({str(tmp_path)!r}) / "builds.log", "a") as log:
                log.write(sys.argv[1] + "\\n")
            time.sleep(1.0)
            (folder / "x.csv").write_text("1\\n")

        print(shared_campaign(F(), "c", build))
        """)
    procs = []
    for k in range(4):
        (tmp_path / f"gw{k}").mkdir()
        env = {"PYTEST_XDIST_WORKER": f"gw{k}", "PATH": "/usr/bin:/bin"}
        procs.append(subprocess.Popen([sys.executable, "-c", code, f"gw{k}"], stdout=subprocess.PIPE,
                                      text=True, env=env))
    outs = [p.communicate(timeout=600)[0].strip() for p in procs]
    assert [p.returncode for p in procs] == [0] * 4
    assert set(outs) == {str(tmp_path / "shared-campaigns" / "c")}
    assert len((tmp_path / "builds.log").read_text().splitlines()) == 1
