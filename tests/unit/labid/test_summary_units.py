"""One unit helper (summary.display_unit) behind the budget console text and the panel."""
from labid.base.summary import budget_text
from labid.base.summary import display_unit


def test_display_unit_by_name():
    assert display_unit("E1") == ("GPa", 1e-9)
    assert display_unit("G12") == ("GPa", 1e-9)
    assert display_unit("nu12") == ("", 1.0)
    assert display_unit("density") == ("kg/m³", 1.0)
    assert display_unit("thickness") == ("m", 1.0)


def _const(value, U, uA, uB):
    uc = (uA ** 2 + uB ** 2) ** 0.5
    return {"value": value, "u_type_a": uA, "u_type_b": uB, "u_combined": uc, "U": U, "U_rel": U / value,
            "contributions": {"type A (fit)": {"u": uA, "share": uA ** 2 / uc ** 2},
                              "thickness": {"u": uB, "share": uB ** 2 / uc ** 2}}}


def test_budget_text_units():
    """E1 = 136.7 GPa with U = 1.6 GPa reads in GPa; nu12 bare; density in kg/m³; U says its k
    (issue 26: the k = 1 std and the k = 2 U were both printed as "+-")."""
    b = {"coverage": "about 95 %", "notes": [],
         "inputs": [{"name": "thickness", "u": 2e-5, "unit": "m", "source": "specimen"}],
         "constants": {"E1": _const(136.7e9, 1.6e9, 0.6e9, 0.6e9),
                       "nu12": _const(0.3, 0.02, 0.006, 0.008),
                       "density": _const(1560.0, 31.0, 10.0, 12.0)}}
    lines = budget_text(b).splitlines()
    e1 = next(x for x in lines if x.strip().startswith("E1 ="))
    assert "136.7 GPa, U (k=2) 1.6 GPa (1.2 %)" in e1
    nu = next(x for x in lines if x.strip().startswith("nu12 ="))
    assert "0.3, U (k=2) 0.02 (6.7 %)" in nu
    rho = next(x for x in lines if x.strip().startswith("density ="))
    assert "1560 kg/m³, U (k=2) 31 kg/m³" in rho
