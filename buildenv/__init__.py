"""buildenv: EnergyPlus simulations of office buildings, neural metamodels of them, calibration to sites.

The pipeline, one module per box: :mod:`buildenv.catalogue` (every variable, defined once),
:mod:`buildenv.weather` (EPW -> W_k), :mod:`buildenv.energyplus` (the shoebox model and the runner),
:mod:`buildenv.campaign` (sampled, parallel, resumable simulation campaigns), :mod:`buildenv.dataset`
(reading and splitting them), :mod:`buildenv.surrogate` (the trained metamodel as a fast week simulator),
:mod:`buildenv.site` and :mod:`buildenv.reference` (measured buildings and the reference-building stand-in)
and :mod:`buildenv.calibration`; :mod:`buildenv.env` is the Gymnasium environment ``BuildingWeek-v0``,
registered on import: ``gymnasium.make("BuildingWeek-v0")``.

``buildenv.load_metamodel()`` loads the shipped default metamodel (torch is imported on first use only).
"""

__version__ = "0.1.0"


def load_metamodel(path=None):
    """The shipped default metamodel, or the checkpoint at ``path`` (see :func:`buildenv.surrogate.load_metamodel`)."""
    from buildenv.surrogate import load_metamodel as _load

    return _load(path)


def _register() -> None:
    from buildenv.registration import register_envs

    register_envs()


_register()
