"""What a calibration is asked for: :class:`CalibrateConfig` and the command's defaults."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from tippetop.models.calibrated import CALIBRATION_FILE

#: The shipped result (the default of ``mujoco.friction=native``).
DEFAULT_OUT = CALIBRATION_FILE
#: How the shipped result is named in the reproduce command (run from the repository's root).
DEFAULT_OUT_SHOWN = "models/calibrated_native.toml"
#: Calibration scenes, ``NAME:T_END_S``: two Group II tops that turn over, from theta0 = 0.1
#: (Fig. 3, A/C = 1, a/R = 0.1) and from theta0 = 0.01 (Fig. 11, a/R = 0.15, n0 = 70 rad/s).
DEFAULT_CALIBRATION = "fig3:6,fig11_n070:6"
#: Held-out scenes: another Group II flip (Fig. 4), Group II below n1 (Fig. 6), Group I
#: (Fig. 7a), Group III above and below n1 (Fig. 8a, 8b), the Fig. 11 intermediate states
#: (n0 = 50, 60 rad/s) and a faster flip (n0 = 80 rad/s).
DEFAULT_HOLDOUT = ("fig4:8,fig6:12,fig7a:8,fig8a:20,fig8b:8,fig11_n050:30,fig11_n060:30,"
                   "fig11_n080:10")
#: MuJoCo timestep of the fit (s). At the settings found, theta(t) at 2e-4 s, 1e-4 s and
#: 5e-5 s agreed to about 1e-3 rad and 1 ms in the inversion time (see the timestep check).
DEFAULT_TIMESTEP_S = 2e-4
DEFAULT_INTEGRATOR = "RK4"
#: Candidate x scene runs the search may use.
DEFAULT_BUDGET_RUNS = 160
#: The searches: ``sysid`` (MuJoCo's identification, :mod:`.identify`; the default) and
#: ``compass`` (the hand-written grid and compass search, :mod:`.fit`, kept to compare).
SEARCHES = ("sysid", "compass")


@dataclass(frozen=True)
class CalibrateConfig:
    """Everything ``tippetop calibrate`` was asked for; the defaults are the command's.

    Attributes:
        calibration: Scenes fitted, ``NAME[:T_END_S],...``.
        holdout: Scenes only reported, ``NAME[:T_END_S],...``.
        out: The calibration file to write (``.toml``).
        force: Overwrite an existing ``out``.
        budget_runs: Candidate x scene runs the search may use.
        timestep_s: MuJoCo timestep of the fit (s).
        integrator: MuJoCo integrator of the fit.
        scheduler: A Dask scheduler address (``tcp://HOST:PORT``), or None for local processes.
        workers: Local worker processes (None: all cores).
        use_cache: Read and write the run cache.
        progress: Print the search's progress on stderr.
        search: ``sysid`` or ``compass`` (:data:`SEARCHES`).
    """

    calibration: str = DEFAULT_CALIBRATION
    holdout: str = DEFAULT_HOLDOUT
    out: str | Path = DEFAULT_OUT
    force: bool = False
    budget_runs: int = DEFAULT_BUDGET_RUNS
    timestep_s: float = DEFAULT_TIMESTEP_S
    integrator: str = DEFAULT_INTEGRATOR
    scheduler: str | None = None
    workers: int | None = None
    use_cache: bool = True
    progress: bool = True
    search: str = "sysid"
