"""Sim-to-real gap diagnosis: the catalogue of unmodelled effects (:mod:`.effects`), their model-side versions
(:mod:`.model_effects`), the diagnosis itself (:mod:`.gap`), localisation in time (:mod:`.localise`) and the blind check
on sites with an injected effect (:mod:`.blind_check`)."""
