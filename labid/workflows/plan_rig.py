"""Write a test plan as a rig file ``labid acquire`` takes (``labid plan --write-rig``).

The user's rig (or the built-in one) is the template, edited in place with tomlkit so its
comments, devices and settings stay: the hammer point and the accelerometers' positions
become the plan's (channels are added by copying the last accelerometer, or the extra ones
removed); with waves recommended, ``[wave_source]`` becomes a pencil-lead break at the
plan's source and the wave device's sensor channels become the legs' near and far sensors
(``distance_m``, ``direction_deg``; the device is taken from the built-in rig when the
template has none), its record long enough for the slowest planned A0 point. The text is
validated (``labid.inputs.rig``, on the specimen) before it is written. Units SI (m, s, Hz).
"""
from __future__ import annotations

import copy
import re
from importlib import resources
from pathlib import Path

import tomlkit

from ..base import atomic
from ..base.errors import UserError
from ..inputs.rig import rig_from_text

__all__ = ["plan_rig_text", "write_plan_rig", "RECORD_MARGIN"]

#: the wave record holds RECORD_MARGIN x the slowest planned arrival at the far sensor
RECORD_MARGIN = 2.0


def _next_physical(phys: str, k: int) -> str:
    m = re.search(r"(\d+)$", phys or "")
    return phys if m is None else phys[:m.start()] + str(int(m.group(1)) + k)


def _device(doc, role: str):
    for name, dev in doc.get("devices", {}).items():
        if dev.get("role") == role:
            return name, dev
    return None, None


def _set_accelerometers(doc, accs: list[dict]) -> None:
    name, dev = _device(doc, "hammer")
    chans = dev["channels"]
    idx = [i for i, c in enumerate(chans) if c.get("kind") == "accelerometer"]
    taken = {str(c["name"]) for d in doc["devices"].values() for c in d.get("channels", [])}
    while len(idx) < len(accs):
        prev = chans[idx[-1]]
        new = copy.deepcopy(prev)
        k = len(idx) + 1
        while f"acc{k}" in taken:
            k += 1
        new["name"] = f"acc{k}"
        taken.add(new["name"])
        if "physical" in new:
            new["physical"] = _next_physical(str(prev["physical"]), 1)
        chans.append(new)
        idx.append(len(chans) - 1)
    for i in reversed(idx[len(accs):]):
        del chans[i]
    for i, a in zip(idx, accs):
        chans[i]["x"] = round(a["x"], 4)
        chans[i]["y"] = round(a["y"], 4)


def _set_waves(doc, waves: dict) -> None:
    src = doc.get("wave_source")
    if src is None or src.get("kind") != "pencil":
        doc["wave_source"] = tomlkit.table()
        src = doc["wave_source"]
        src["kind"] = "pencil"
        src["rise_s"] = 1.0e-6
        src["force_n"] = 1.0
    src["x"] = round(waves["source"]["x"], 4)
    src["y"] = round(waves["source"]["y"], 4)
    if "channel" in src:
        del src["channel"]
    name, dev = _device(doc, "wave")
    if dev is None:
        builtin = tomlkit.parse(resources.files("labid.data").joinpath("rig_default.toml").read_text())
        name, dev = _device(builtin, "wave")
        doc["devices"][name] = dev
        dev = doc["devices"][name]
    chans = dev["channels"]
    sensors = [i for i, c in enumerate(chans) if "distance_m" in c]
    proto = copy.deepcopy(chans[sensors[0]]) if sensors else tomlkit.inline_table()
    for i in reversed(sensors):
        del chans[i]
    names = []
    for k, leg in enumerate(waves["legs"]):
        for j, d in enumerate((leg["near_m"], leg["far_m"])):
            c = copy.deepcopy(proto)
            c["name"] = f"mfc{len(names) + 1}"
            if "physical" in c:
                c["physical"] = _next_physical(str(proto["physical"]), len(names))
            c["distance_m"] = round(d, 4)
            c["direction_deg"] = float(leg["direction_deg"])
            for key in ("x", "y"):
                if key in c:
                    del c[key]
            chans.append(c)
            names.append(c["name"])
    trig = dev.get("trigger")
    if trig is not None and trig.get("channel") not in [c["name"] for c in chans]:
        trig["channel"] = names[0]
    t_max = max(leg["far_m"] / min(leg["cg_m_s"]) for leg in waves["legs"] if leg.get("cg_m_s"))
    rate = float(dev["rate_hz"])
    need = int(dev.get("pretrigger", 0)) + int(RECORD_MARGIN * t_max * rate)
    if int(dev["samples"]) < need:
        dev["samples"] = need


def _edited(template_text: str, doc: dict) -> str:
    """The template rig's TOML text with the plan ``doc`` (``PlanResult.to_dict()``) applied."""
    rig = tomlkit.parse(template_text)
    rec = doc["recommended"]
    if "hammer" not in rig:
        raise UserError("the rig has no [hammer]: a modal test needs one", key="--write-rig")
    rig["hammer"]["x"] = round(rec["hammer"]["x"], 4)
    rig["hammer"]["y"] = round(rec["hammer"]["y"], 4)
    _set_accelerometers(rig, rec["accelerometers"])
    if doc["waves"].get("recommended"):
        _set_waves(rig, doc["waves"])
    rig["name"] = f"{rig.get('name', 'rig')} -- layout by labid plan ({doc['specimen']})"
    return tomlkit.dumps(rig)


def plan_rig_text(result, src: str = "<planned rig>") -> str:
    """The recommended rig's text for ``result`` (a ``PlanResult``), validated as a rig file
    and on the plan's specimen."""
    text = _edited(result.template.text, result.doc)
    rig = rig_from_text(text, src)
    rig.check_specimen(result.specimen.length, result.specimen.width)
    return text


def write_plan_rig(result, path: str | Path) -> str:
    """Write the recommended rig to ``path`` (atomically); its text."""
    text = plan_rig_text(result, str(path))
    atomic.write_text(Path(path), text, key="--write-rig")
    return text
