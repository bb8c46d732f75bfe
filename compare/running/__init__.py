"""Running plans: the engines, the parallel cached runner, the cost model and the output files.

:mod:`.engines` runs one plan and summarises it; :mod:`.runner` runs many, in parallel and
cached; :mod:`.cost` and :mod:`.progress` say how long they take; :mod:`.io`,
:mod:`.leftovers` and :mod:`.interrupt` write outputs atomically, clean up after a killed
run and stop cleanly on Ctrl-C or SIGTERM.
"""
