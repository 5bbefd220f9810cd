"""Independent "reality" generators for the diagnosis proof (never imported by the package).

Each sub-package was written by a developer who saw only ``../shared/PHYSICS.md``,
``../shared/INTERFACE.md`` and a spec of the mechanisms in words, never the diagnosis code.
Common contract: ``python -m realities.<name> --list`` and
``python -m realities.<name> --case CASE --seed N -o OUTDIR [--minutes M]`` write
``OUTDIR/recording/`` (the bag), ``OUTDIR/twin/`` (noise-free, same slip stamps),
``OUTDIR/model.tir`` (the file a user diagnoses with) and ``OUTDIR/truth.json``.
"""
