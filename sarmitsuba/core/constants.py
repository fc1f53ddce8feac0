"""Physical constants (SI units), with their sources."""

#: Speed of light in vacuum [m/s]; exact by definition (SI, 2019).
SPEED_OF_LIGHT = 299_792_458.0

#: Vacuum permittivity epsilon_0 [F/m]; CODATA 2018.
VACUUM_PERMITTIVITY = 8.8541878128e-12

#: Boltzmann constant k_B [J/K]; exact by definition (SI, 2019).
BOLTZMANN = 1.380649e-23
