"""The Gymnasium environment ``BuildingWeek-v0`` (:mod:`.building_week`; its vector env :mod:`.vector`, their scoring
core :mod:`.building` and arguments :mod:`.arguments`), its actions, observations and objectives, the EnergyPlus
backend that verifies settings on a site (:mod:`.energyplus_backend`) and its registration."""
