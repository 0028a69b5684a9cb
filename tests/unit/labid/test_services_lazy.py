"""The lazy facade (issue 29): ``labid.services`` re-exports every name of its ``__all__`` from the
module it is written in, and a command imports only the workflows it runs (each checked in a
fresh interpreter: ``sys.modules`` after importing the command's module)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from labid import base, display, inference, picks, runresults, services
from labid.workflows import analysis, damping

#: what the identification and the diagnosis never run: the acquisition, the analysis, the plan,
#: the simulated rig, the instruments, import/export, the display, and the libraries only they use
NOT_FOR_INFERENCE = ("mock_hw", "drivers.serial_instruments", "drivers.nidaq", "labid.workflows.acquisition",
                     "labid.workflows.analysis", "labid.workflows.waveloop", "labid.workflows.plan",
                     "labid.workflows.cluster", "labid.io", "labid.display", "labid.picks", "labid.store",
                     "engine.modal", "engine.wavefeatures", "engine.design", "h5py", "pywt", "tomlkit",
                     "scipy.signal", "scipy.stats")


def _modules_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, check=True)
    return set(json.loads(out.stdout.splitlines()[-1]))


def test_every_exported_name_is_the_object_of_its_module():
    sources = (inference, runresults, picks, display, analysis, damping, base.results)
    for name in services.__all__:
        value = getattr(services, name)
        owners = [m for m in sources if name in vars(m)]
        assert all(vars(m)[name] is value for m in owners), name
    assert "run_diagnosis" in dir(services)
    with pytest.raises(AttributeError, match="no_such_name"):
        services.no_such_name  # noqa: B018


def _loaded(mods: set[str], packages: tuple[str, ...]) -> list[str]:
    return sorted(m for m in mods if any(m == p or m.startswith(p + ".") for p in packages))


def test_the_facade_alone_imports_no_workflow_and_no_scipy():
    mods = _modules_after("import labid.services")
    assert _loaded(mods, ("labid.workflows", "labid.inference", "labid.store", "engine", "mock_hw", "scipy",
                          "h5py")) == []


@pytest.mark.parametrize("command", ["diagnose", "identify"])
def test_identify_and_diagnose_import_only_what_they_run(command):
    mods = _modules_after(f"import labid.cli.main, labid.cli.{command}\n"
                          "from labid import services\n"
                          "services.run_diagnosis, services.run_identification, services.store_for_features\n"
                          "import labid.workflows.diagnosis, engine.gap    # what run_diagnosis imports when called")
    assert "labid.workflows.identification.flow" in mods and "engine.fit" in mods
    assert _loaded(mods, NOT_FOR_INFERENCE) == []
