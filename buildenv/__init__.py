"""buildenv: EnergyPlus simulations of office buildings, turned into datasets for neural metamodels.

The pipeline, one module per box: :mod:`buildenv.catalogue` (every variable, defined once),
:mod:`buildenv.weather` (EPW -> W_k), :mod:`buildenv.energyplus` (the shoebox model and the runner),
:mod:`buildenv.campaign` (sampled, parallel, resumable simulation campaigns) and :mod:`buildenv.dataset`
(reading and splitting them).
"""

__version__ = "0.1.0"
