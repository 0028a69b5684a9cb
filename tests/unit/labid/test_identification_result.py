"""The typed identification result (``labid.base.results.Identification``): one shape for the
command line, the panel, the report and the run file, and one definition of "identified"."""
from __future__ import annotations

from labid.base.results import Identification
from labid.io.exporters import constants_rows

VERDICT = {
    "parameters": {"E1": {"value": 136.7e9, "std": 0.1e9, "identified": True},
                   "nu12": {"value": 0.2978, "std": 0.006, "identified": False,
                            "reason": "held at 0.25 under a weak prior (log-std 0.3)"},
                   "G23": {"value": 3.2e9, "std": 1.2e9, "identified": False, "reason": "relative std 0.37 > 0.3"}},
    "converged": True, "residual": {"modal_rms_rel": 1e-4, "waves_rms_rel": None}, "identified": False,
    "held": {"nu12": {"value": 0.25, "reason": "relative std 0.589 > 0.3 at the start"}},
    "fit": {"consistent": True}, "identifiability": {"parameters": {"E1": {"identified": True},
                                                                     "nu12": {"identified": False},
                                                                     "G23": {"identified": False}}},
    "blocks": {"modal": {"kind": "modal"}, "waves[0]:A0@0deg": {"kind": "waves"}},
}


def test_identified_has_one_definition_and_every_reader_uses_it():
    r = Identification.from_dict(VERDICT)
    assert r.status("E1") == (True, "")
    assert r.status("nu12")[0] is False and "held at 0.25" in r.status("nu12")[1]   # held: never identified
    assert r.status("G23") == (False, "relative std 0.37 > 0.3")
    assert r.status("E2") == (False, "not fitted")
    assert r.identified is False
    # the CSV's identified column is that definition
    rows = {row[1]: row[6] for row in constants_rows(VERDICT)}
    assert rows == {"E1": True, "nu12": False, "G23": False}


def test_the_data_kinds_are_read_from_every_stored_shape():
    cli = dict(VERDICT, data=["modal", "waves"])
    panel = dict(VERDICT, data="combined")                # the panel's older shape: kinds from the blocks
    bare = {k: v for k, v in VERDICT.items() if k != "blocks"}
    assert Identification.from_dict(cli).data == ("modal", "waves")
    assert Identification.from_dict(panel).data == ("modal", "waves")
    assert Identification.from_dict(panel).data_set == "combined"
    assert Identification.from_dict(dict(bare, data="waves")).data == ("waves",)


def test_to_dict_keeps_the_contract_keys_and_reads_back_equal():
    r = Identification(VERDICT, ("modal",), "CFRP", {"E1": 136.7e9}, budget={"constants": {}})
    d = r.to_dict()
    assert {"parameters", "converged", "residual"} <= set(d)      # CONTRACT section 3
    assert d["data"] == ["modal"] and d["data_set"] == "modal" and d["uncertainty_budget"] == {"constants": {}}
    assert Identification.from_dict(d) == r


def test_a_result_without_a_verdict_reads_its_identifiability():
    old = {"parameters": {"E": {"value": 70e9, "std": 1e9}}, "converged": True,
           "identifiability": {"parameters": {"E": {"identified": True}}}}
    assert Identification.from_dict(old).status("E") == (True, "")
    assert Identification.from_dict(dict(old, fit={"consistent": False})).status("E")[0] is False
