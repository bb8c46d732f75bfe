"""Studies: the work behind each measuring command, which starts runs and reads them.

:mod:`.crossval` (a scene across modes, against the theory and the reference), :mod:`.growth`
and :mod:`.threshold` (critical spins measured), :mod:`.sweep`, :mod:`.atlas` (the group
diagram measured), :mod:`.matrix` and :mod:`.attribution` (engines side by side), :mod:`.refit`
(the reference rerun with a realised law), :mod:`.validate` (an MJCF top checked; its contact
tuned by :mod:`tippetop.compare.tuning`), :mod:`.fidelity` and :mod:`.contact_search` (where
the tuned contact follows the reference, and why not), :mod:`.render` (a video of a run),
:mod:`.bench` (the reference against its peers), :mod:`.defaults`, and the package
:mod:`.accuracy`. What they measure is computed by :mod:`tippetop.compare.measures`.
"""
