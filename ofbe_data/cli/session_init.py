"""The manifest ``ofbe-session init`` writes (:mod:`ofbe_data.cli.session`): the YAML with each
decision's evidence as a comment beside its key (:func:`manifest_text`). What the folder's files
are (data files, devices, recordings, the power cycle) is found by :mod:`ofbe_data.io.detection`.
"""

from __future__ import annotations

from typing import Any

import yaml

from ofbe_data.io.detection import DeviceEntry
from ofbe_data.io.manifest import MANIFEST_FORMAT


def _flow(value: Any) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=10**6, allow_unicode=True, sort_keys=False)
    text = text.strip()
    if text.endswith("..."):
        text = text[:-3].strip()
    return text


def _line(indent: str, key: str, value: Any, why: str | None) -> str:
    out = f"{indent}{key}: {_flow(value)}"
    return out + f"  # {' '.join(why.split())}" if why else out


def manifest_text(top: dict[str, Any], top_why: dict[str, str], devices: list[DeviceEntry],
                  recordings: list[tuple[str, dict[str, str]]], file_notes: dict[str, str]) -> str:
    """The manifest as YAML with each decision's evidence as a comment beside its key."""
    out = ["# Written by ofbe-session init from the files in this folder. The comments give the",
           "# evidence of each detected value; edit what is wrong, then run: ofbe-session check <folder>",
           _line("", "format", MANIFEST_FORMAT, None)]
    out += [_line("", k, v, top_why.get(k)) for k, v in top.items()]
    out.append("devices:")
    for d in devices:
        out.append(f"  {d.id}:")
        out += [f"    # {' '.join(n.split())}" for n in d.notes]
        out.append(_line("    ", "model", d.model, d.evidence.get("model")))
        out.append(_line("    ", "role", d.role, d.evidence.get("role")))
        out.append(_line("    ", "format", d.format, d.evidence.get("format")))
        out += [_line("    ", k, v, d.evidence.get(k)) for k, v in d.entry.items()]
    out.append("recordings:")
    for rid, files in recordings:
        out.append(f"  - id: {_flow(rid)}")
        shared = dict.fromkeys(files.values())  # devices reading one file share its note
        out += [f"    # {rel}: {file_notes[rel]}" for rel in shared if file_notes.get(rel)]
        out.append(_line("    ", "files", files, None))
    return "\n".join(out) + "\n"
