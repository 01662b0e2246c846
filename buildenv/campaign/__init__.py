"""Simulation campaigns: sampled settings and buildings (:mod:`.sampling`), parallel resumable EnergyPlus runs
(:mod:`.runs`) and the HDF5 datasets they write (:mod:`.dataset`)."""
