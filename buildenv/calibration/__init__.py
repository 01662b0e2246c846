"""Calibration of a site: the whole calibration (:mod:`.calibrate`, ``calibrate_site``), the calibration problem
and CMA-ES (:mod:`.problem`), its gradient variant (:mod:`.gradient`), calibrating EnergyPlus directly
(:mod:`.energyplus`) and the calibration plot (:mod:`.plot`)."""
