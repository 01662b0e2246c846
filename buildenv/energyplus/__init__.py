"""EnergyPlus: the shoebox model builder, the runner, the reference-office stand-in and effect injections."""
