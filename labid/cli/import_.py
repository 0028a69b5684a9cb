"""``labid import FILES..``: recordings of other systems (TDMS, UFF58, WAV, MAT, CSV) into a run file.

``labid import FILES... --rig RIG.toml --specimen SPEC.toml --out RUN.h5`` stores them as
shots of the rig's channels.

``--map 'file_channel=rig_channel,...'`` says which channel of the files is which rig channel
(``FILE:channel`` names a channel of one file); several files on a common trigger make one
shot. Rate, pre-trigger and units come from the files where they state them, else from
``--rate``, ``--pretrigger``, ``--units``; mismatches are refused in one line (exit 2). The
``--json`` result: ``out``, ``kind``, ``shots``, ``channels``, ``rate_hz``, ``samples``,
``pretrigger``, ``units``, ``notes``, ``calibration``. Formats and rules: docs/import-export.md.
"""
from __future__ import annotations

import sys

from .. import services
from .options import add_json_option, bounded, count
from ..base.errors import UserError


def register(sub) -> None:
    p = sub.add_parser("import", help="recordings of other systems (TDMS, UFF58, WAV, MAT, CSV) into a run file",
                       description=__doc__.splitlines()[0])
    p.add_argument("files", nargs="+", metavar="FILE", help="recordings (.tdms, .uff/.unv, .wav, .mat, .csv/.txt)")
    p.add_argument("--rig", required=True, metavar="RIG.toml", help="rig file the recordings were made on")
    p.add_argument("--specimen", required=True, metavar="SPEC.toml", help="specimen file (or cfrp, aluminium)")
    p.add_argument("--out", required=True, metavar="RUN.h5", help="run file to create or append to")
    p.add_argument("--map", default=None, metavar="F=R,..",
                   help="file channel = rig channel, comma-separated (FILE:channel for one file's channel); "
                        "default: the file channels named as rig channels")
    p.add_argument("--rate", type=bounded(float, 1e-3, 1e10, "a sample rate in Hz"), default=None, metavar="HZ",
                   help="sample rate, for files that do not state it")
    p.add_argument("--pretrigger", type=count(2 ** 31 - 1, "a number of samples"), default=None, metavar="N",
                   help="samples before the trigger, for files that do not state it")
    p.add_argument("--units", default=None, metavar="R=U,..",
                   help="unit per rig channel for files that do not state it: m/s^2, g, N, V, mV, ... "
                        "(a leading factor scales: 2.5V = one file unit is 2.5 V)")
    p.add_argument("--kind", choices=("hammer", "wave"), default=None,
                   help="shot kind (default: the role of the device of the mapped channels)")
    p.add_argument("--crop", action="store_true",
                   help="records of different lengths or pre-triggers: keep the span they all cover")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    res = services.import_records(args.files, args.rig, args.specimen, args.out, args.map, rate_hz=args.rate,
                                  pretrigger=args.pretrigger, units_text=args.units, kind=args.kind, crop=args.crop)
    services.warn_calibration(res.get("calibration"), prefix="labid import")
    if getattr(args, "json", None) != "-":
        w = sys.stdout.write
        for part in res.get("parts") or [res]:       # several devices (a labid export UFF): one line each
            w(f"imported {len(part['shots'])} {part['kind']} shot(s) into {res['out']}: "
              f"{part['samples']} samples at {part['rate_hz']:g} Hz, {part['pretrigger']} before the trigger\n")
        for rig_ch, src in res["channels"].items():
            w(f"  {rig_ch:>10} <- {src} [{res['units'][rig_ch]}]\n")
        for note in res["notes"]:
            w(f"  note: {note}\n")
    if not res["shots"]:
        raise UserError("no shot imported", key="FILES")
    return res
