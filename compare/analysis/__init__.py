"""The analysis: the theory, run metrics, and the work behind each measuring command.

:mod:`.theory` (the paper's formulas), :mod:`.metrics` (a run's summary numbers),
:mod:`.crossval` (a scene across modes, against the theory and the reference), :mod:`.growth`
and :mod:`.threshold` (critical spins measured), :mod:`.sweep`, :mod:`.atlas` (the group
diagram measured), :mod:`.validate` (an MJCF top checked), :mod:`.bench` (the reference
against its peers), :mod:`.defaults`, and the packages :mod:`.accuracy` and :mod:`.calibrate`.
"""
