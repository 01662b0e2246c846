"""The trained metamodel on the building side: the Surrogate that predicts weeks in physical units
(:mod:`.surrogate`), training from a campaign (:mod:`.training`) and worker threads for its calls (:mod:`.threads`)."""
