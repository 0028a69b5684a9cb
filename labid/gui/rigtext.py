"""Small edits of a rig TOML text that keep its comments: trigger level and pre-trigger."""
from __future__ import annotations

import re


def _section(lines: list[str], device: str) -> tuple[int, int]:
    head = re.compile(rf"^\s*\[\s*devices\.{re.escape(device)}\s*\]")
    start = next((i for i, ln in enumerate(lines) if head.match(ln)), None)
    if start is None:
        raise KeyError(device)
    end = next((i for i in range(start + 1, len(lines)) if lines[i].lstrip().startswith("[")), len(lines))
    return start, end


def set_device_values(text: str, device: str, *, level_v: float | None = None,
                      pretrigger: int | None = None) -> str:
    """``text`` with ``devices.<device>.pretrigger`` and the trigger's ``level_v`` replaced
    (or added). Raises KeyError if the device table is not in the text."""
    lines = text.splitlines()
    start, end = _section(lines, device)
    if pretrigger is not None:
        pat = re.compile(r"^(\s*pretrigger\s*=\s*)([^#\s]+)(.*)$")
        for i in range(start + 1, end):
            m = pat.match(lines[i])
            if m:
                lines[i] = f"{m.group(1)}{int(pretrigger)}{m.group(3)}"
                break
        else:
            lines.insert(start + 1, f"pretrigger = {int(pretrigger)}")
            end += 1
    if level_v is not None:
        pat = re.compile(r"(level_v\s*=\s*)([-+0-9.eE]+)")
        for i in range(start + 1, end):
            if re.match(r"^\s*trigger\s*=", lines[i]) and pat.search(lines[i]):
                lines[i] = pat.sub(lambda m: f"{m.group(1)}{level_v:g}", lines[i], count=1)
                break
        else:
            raise KeyError(f"devices.{device}.trigger")
    return "\n".join(lines) + ("\n" if text.endswith("\n") else "")
