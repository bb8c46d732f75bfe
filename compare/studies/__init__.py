"""Studies: the work behind each measuring command, which starts runs and reads them.

:mod:`.crossval` (a scene across modes, against the theory and the reference), :mod:`.growth`
and :mod:`.threshold` (critical spins measured), :mod:`.sweep`, :mod:`.atlas` (the group
diagram measured), :mod:`.matrix` and :mod:`.attribution` (engines side by side), :mod:`.refit`
(the reference rerun with a realised law), :mod:`.validate` and :mod:`.tune` (an MJCF top
checked and its contact tuned), :mod:`.render` (a video of a run), :mod:`.bench` (the
reference against its peers), :mod:`.defaults`, and the packages :mod:`.accuracy` and
:mod:`.calibrate`. What they measure is computed by :mod:`tippetop.compare.measures`.
"""
