"""The Gymnasium environment ``BuildingWeek-v0`` (:mod:`.building_week`), its actions, observations and objectives,
the EnergyPlus backend that verifies settings on a site (:mod:`.energyplus_backend`) and its registration."""
