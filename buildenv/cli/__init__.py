"""The ``buildenv`` command line: one module per command group (:mod:`.main` holds the parser and the entry point)."""
