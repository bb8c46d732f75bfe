"""MuJoCo: MJCF loading, stepping in the requested friction mode, observables."""
