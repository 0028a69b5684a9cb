"""Free-free Mindlin (first-order shear) laminated plate, finite elements.

Paper section 2 (Eqs. 1-14): displacements u = u0 + z bx, v = v0 + z by,
w = w0; energy from the laminate resultants A, B, D, H (``engine.laminate.abdh``,
shear factor 5/6). Units SI: m, kg, s, Pa; eigenvalues omega^2 in rad^2/s^2.

Modules (each readable alone):

* :mod:`.element` -- the 16-node bicubic element with assumed transverse shear
  strains: shape functions, quadrature, reference matrices;
* :mod:`.stiffness` -- material linearity: 21 laminate coefficients per material,
  their derivatives with respect to the engineering constants;
* :mod:`.mesh` -- tensor-grid meshes, uniform or graded at the free edges;
* :mod:`.field` -- thickness field: per-element weights of the powers of the
  thickness scale (``PlateModel.with_thickness_field``);
* :mod:`.sparse` -- the fixed sparse pattern, element scatter and eigen blocks
  (the measured reason for the hand-made pattern is in its docstring);
* :mod:`.model` -- ``PlateModel`` (precomputed parts, solve per parameter set,
  point masses, springs, stiffness loss, thickness field, sensitivities) and ``Modes``;
* :mod:`.labels` -- mode family labels (m, n) from the shapes (``mode_families``);
* :mod:`.sensitivity` -- eigenvalue sensitivities from one solve: per laminate coefficient
  and inertia (``PlateModel.eigen_sensitivities``), and to the geometry, density and point
  mass positions (``geometry_sensitivities``).

Public API (re-exported here): ``PlateModel``, ``Modes``, ``Mesh``, ``FEError``,
``natural_frequencies``, ``mode_families``, ``geometry_sensitivities``, ``coefficients_from_abdh``, ``DEFAULT_ELEMENTS``,
``EDGE_LAYER``, ``COEF_NAMES``, ``Q_NAMES``, ``NODE_DOF``.

The workflow (run by the test suite as a doctest): a laminate, a mesh, the model built
once, its modes at any parameter set. NAFEMS FV12, a free 10 m square steel plate 50 mm
thick, has the elastic modes 1.622, 2.360, 2.922, 4.190, 4.190 Hz; a 4 x 4 mesh gives

>>> import numpy as np
>>> from engine.laminate import Laminate, Material, Ply
>>> from engine.plate import Mesh, PlateModel
>>> steel = Material.isotropic_from(200e9, 8000.0, nu=0.3)
>>> plate = PlateModel.build(Laminate([Ply(steel, 0.0, 0.05)]), 10.0, 10.0, Mesh.graded(10.0, 10.0, 4, ()))
>>> np.round(plate.solve(5).frequencies_hz, 2)
array([1.62, 2.36, 2.92, 4.19, 4.19])

and the same model at other constants (the parts are linear in them: no reassembly),
e.g. a 10 % stiffer steel, sqrt(1.1) x higher:

>>> f = plate.solve(1, params={"E": 220e9, "G": 220e9 / 2.6}).frequencies_hz
>>> round(float(f[0] / plate.solve(1).frequencies_hz[0]) ** 2, 4)
1.1

Package-internal (public names shared by the modules of this package; not for
other layers): ``element.shape_2d``, ``element.combo_scales``,
``element.reference_matrices``, ``element.SYM3``/``SYM2``, ``stiffness.q_vector``,
``stiffness.q_derivatives``, ``stiffness.material_maps``, ``sparse.Pattern``,
``sparse.Block``, ``sparse.point_entries``, ``sparse.Added``, ``sparse.symmetric_lu``, ``field.COEF_POWER``, ``field.thickness_weights``,
``field.field_data``, ``sensitivity.coefficient_energies``.
"""
from .element import NODE_DOF, FEError
from .labels import mode_families
from .mesh import DEFAULT_ELEMENTS, EDGE_LAYER, Mesh
from .model import Modes, PlateModel, natural_frequencies
from .sensitivity import geometry_sensitivities
from .stiffness import COEF_NAMES, Q_NAMES, coefficients_from_abdh

__all__ = ["Mesh", "Modes", "PlateModel", "natural_frequencies", "mode_families", "geometry_sensitivities",
           "coefficients_from_abdh",
           "DEFAULT_ELEMENTS", "EDGE_LAYER", "COEF_NAMES", "Q_NAMES", "NODE_DOF", "FEError"]
