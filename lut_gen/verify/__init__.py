"""Independent references for the tables: a brute-force per-wavelength integrator and a
spectral Monte Carlo path tracer. Not imported by ``import lut_gen``: only tests and benches
that check the tables load it."""
