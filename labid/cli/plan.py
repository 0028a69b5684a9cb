"""``labid plan``: design the test before the plate is touched (issue 25, docs/plan.md).

From the specimen (nominal constants, uncertain by ``--prior``) and the rig (its hammer,
band, accelerometers), recommends where the accelerometers go and where to tap, whether
guided waves are needed (directions, band, source, sensor distances), and predicts the
relative std of every constant for the recommended plan, the user's rig and each
``--compare`` rig. ``--write-rig`` writes the recommended rig file (``labid acquire --rig``
takes it), ``--plot`` the figure, ``--json`` the result: ``recommended``, ``rigs`` (each
with ``constants.<name>.std_rel``, ``worst_std_rel``, ``rank`` for compared rigs),
``waves``, ``constants`` (identifiability), ``fitted``, ``held``, ``identify``.
"""
from __future__ import annotations

from .. import services
from ..base import progress as progress_mod
from ..base.summary import stream
from .options import add_json_option


def register(sub) -> None:
    p = sub.add_parser("plan", help="design the test: sensor and tap layout, waves, predicted stds",
                       description=__doc__.splitlines()[0])
    p.add_argument("spec", metavar="SPEC.toml", help="specimen file, or a built-in name ('cfrp', 'aluminium')")
    p.add_argument("--rig", metavar="RIG.toml", help="your rig (default: the built-in rig as template)")
    p.add_argument("--want", metavar="E1,E2,G12", help="constants to identify (default: all of the material's)")
    p.add_argument("--target-u", default="2%", metavar="U",
                   help="target relative standard uncertainty of each wanted constant (default 2%%)")
    p.add_argument("--prior", default=None, metavar="U|NAME=U,...",
                   help="relative std of the datasheet values (default 10%% each)")
    p.add_argument("--budget", default="none", metavar="none|specimen|FILE.toml",
                   help="add the type-B inputs of an [uncertainty] table (the specimen's, or a file's; "
                        "defaults as labid identify) to the predictions")
    p.add_argument("--compare", nargs="+", default=[], metavar="RIG.toml", help="candidate rigs to rank")
    p.add_argument("--write-rig", metavar="OUT.toml", help="write the recommended rig file")
    p.add_argument("--plot", metavar="PNG", help="write the figure (plate, sensors, tap, nodal lines, stds)")
    p.add_argument("--sensors", type=int, default=None, metavar="N",
                   help="accelerometers to place (default: as many as the rig has)")
    p.add_argument("--grid", type=int, default=15, metavar="N", help="candidate grid N x N (default 15, 3..41)")
    p.add_argument("--margin", default="0.02", metavar="M", help="edge margin of the grid, m (default 0.02)")
    p.add_argument("--draws", type=int, default=6, metavar="N",
                   help="parameter sets over the prior the plan must hold for (default 6, 1..32)")
    p.add_argument("--criterion", default="MV", choices=("MV", "D", "A"),
                   help="MV: the largest relative variance of the fitted constants (default: every "
                        "wanted constant has the same target); D: log-det; A: sum of variances (over the draws)")
    p.add_argument("--sigma-f", default="0.1%", metavar="U",
                   help="relative std of a well excited peak's frequency (default 0.1%%)")
    p.add_argument("--mass-u", default="10%", metavar="U",
                   help="relative uncertainty of each accelerometer's mass (default 10%%)")
    p.add_argument("--max-modes", type=int, default=60, metavar="N", help="modes in the model (default 60)")
    p.add_argument("--waves", default="auto", choices=("auto", "yes", "no"),
                   help="guided waves: only when they pay (auto), always planned, never")
    p.add_argument("--fit", default="auto", choices=("auto", "wanted"),
                   help="fit the wanted constants and those the data determine (auto, as labid identify), "
                        "or the wanted ones only")
    p.add_argument("--seed", type=int, default=0, help="seed of the prior draws and random starts")
    add_json_option(p)
    p.set_defaults(func=run)


def run(args) -> dict:
    result = services.plan_test(
        args.spec, args.rig, args.compare, progress=lambda msg: progress_mod.note(f"labid plan: {msg}"),
        want=args.want, target_u=args.target_u, prior=args.prior, budget=args.budget, grid=args.grid,
        margin=args.margin, sensors=args.sensors, draws=args.draws, criterion=args.criterion,
        sigma_f=args.sigma_f, mass_u=args.mass_u, max_modes=args.max_modes, waves=args.waves, fit=args.fit, seed=args.seed)
    if args.write_rig:
        result.write_rig(args.write_rig)
    if args.plot:
        result.save_figure(args.plot)
    w = stream(args)
    if w is not None:
        w.write(result.text())
        for what, path in (("rig file", args.write_rig), ("figure", args.plot)):
            if path:
                w.write(f"{what}: {path}\n")
    return result.to_dict()
