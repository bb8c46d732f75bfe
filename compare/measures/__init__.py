"""Pure measurements: functions of a run's numbers, the top and the theory; nothing runs here.

:mod:`.series` (a run's metrics from its observables table), :mod:`.summary` (what a run's
summary says: finished or failed, what ran), :mod:`.friction_realised` (the friction law a run
realised), :mod:`.theory` (the paper's formulas, with :mod:`.roots`), :mod:`.verdict` (whether
a run agrees with the theory, and where it departs from the reference), :mod:`.checks`
(``validate``'s checks) and :mod:`.tolerances` (how far a metric may move from its baseline).
Every other room of :mod:`tippetop.compare` may import these; they import none of them.
"""
