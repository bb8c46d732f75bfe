"""Running plans: the engines, the parallel cached runner, the cost model and the output files.

:mod:`.engines` runs one plan and summarises it; :mod:`.runner` runs many, in parallel
(:mod:`.pool`, :mod:`.cluster`) and cached (:mod:`.cache`), each a :mod:`.tasks` task;
:mod:`.cost`, :mod:`.compiling` and :mod:`.progress` say how long they take; :mod:`.io`,
:mod:`.leftovers` and :mod:`.interrupt` write outputs atomically, clean up after a killed
run and stop cleanly on Ctrl-C or SIGTERM; :mod:`.options` says how a study runs its runs
(:class:`~.options.RunOptions`: the scheduler, the workers, the cache, the progress).
"""
