"""buildenv: EnergyPlus simulations of office buildings, neural metamodels of them, calibration to sites.

The pipeline, one subpackage per stage:

- :mod:`buildenv.energyplus`: the shoebox model, the runner and the reference-office stand-in;
- :mod:`buildenv.weather`: EPW files read into W_k, and morphed weather;
- :mod:`buildenv.campaign`: sampled, parallel, resumable simulation campaigns and their datasets;
- :mod:`buildenv.metamodel`: the trained metamodel as a fast week simulator, and its training;
- :mod:`buildenv.sites`: measured buildings (site folders) and their week simulators;
- :mod:`buildenv.calibration`: calibrating a site's building parameters to its measurements;
- :mod:`buildenv.diagnosis`: the sim-to-real gap diagnosis and its catalogue of unmodelled effects;
- :mod:`buildenv.env`: the Gymnasium environment ``BuildingWeek-v0``, registered on import
  (``gymnasium.make("BuildingWeek-v0")``);
- :mod:`buildenv.cli`: the ``buildenv`` command line.

Shared by all: :mod:`buildenv.catalogue` (every variable, defined once), :mod:`buildenv.schedules`,
:mod:`buildenv.metrics`, :mod:`buildenv.defaults`, :mod:`buildenv.plotting` and :mod:`buildenv.errors`.
``buildenv.load_metamodel()`` loads the shipped default metamodel (torch is imported on first use only).
"""

__version__ = "0.1.0"


def load_metamodel(path=None):
    """The shipped default metamodel, or the checkpoint at ``path`` (:func:`.metamodel.surrogate.load_metamodel`)."""
    from buildenv.metamodel.surrogate import load_metamodel as _load

    return _load(path)


def _register() -> None:
    from buildenv.env.registration import register_envs

    register_envs()


_register()
