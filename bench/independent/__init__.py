"""Models that share no code with labid's engine, to generate and check data labid did not make.

* :mod:`.ritz_plate`: a Rayleigh-Ritz Mindlin laminated plate (Legendre bases, quadrature fields,
  point masses and springs, shallow initial curvature), the plate half of the gap bench's
  independent generator (``bench/blind_independent.py``).
"""
