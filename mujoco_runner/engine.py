"""A scene run in MuJoCo, summarised like the reference ODE.

Maps a :class:`models.scene.Scene` to :func:`mujoco_runner.run.simulate_mujoco`: the friction
mode, integrator, timestep and contact settings come from the scene's ``[mujoco]`` section, the
contact dimensionality from its ``[effects]`` (only what the scene switches on is simulated):

* paper mode: condim 1 (frictionless contact); the harness applies the scene's friction law at
  the contact point. Torsional or rolling friction cannot be applied in this mode. The contact
  is made stiff (``PAPER_SOLREF``) unless the scene sets ``mujoco.solref``: the paper's is rigid.
* native mode: MuJoCo's own friction, condim 3 for sliding, 4 with torsional, 6 with rolling
  friction, 1 with no friction at all. Unless the scene sets them, the native contact settings
  are the calibrated ones shipped in ``models/calibrated_native.toml`` (``tippetop calibrate``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from tippetop.compare.engines import EngineRun
from tippetop.compare.metrics import first_inversion_time, jellett_scale, summary
from tippetop.models.calibrated import calibrated_native_settings
from tippetop.models.errors import TippetopError
from tippetop.models.mjcf import MUJOCO_DEFAULT_ROLLING, MUJOCO_DEFAULT_TORSIONAL
from tippetop.models.scene import Scene

#: Stand-in for an integration tolerance in the energy check: soft contacts store a little
#: elastic energy in the penetration that the table's E leaves out (about 1e-5 of E0 at rest).
MUJOCO_ENERGY_RTOL = 1e-6
#: Paper mode's contact time constant (s) unless the scene sets mujoco.solref: the paper's
#: contact is rigid, and MuJoCo's default 0.02 s lets the ball sink 0.37 mm (2.5 % of R),
#: which moves theta(t) by ~0.014 rad on Fig. 3; 0.5 ms sinks it < 1 um (~2e-4 rad). MuJoCo
#: raises a time constant below 2 dt to 2 dt by itself (refsafe), so coarse steps stay stable.
PAPER_SOLREF = (5e-4, 1.0)
#: Default row spacing of the table (s), coarsened for long runs to at most 20,000 rows.
DEFAULT_SAMPLE_DT_S = 1e-3


def native_condim(scene: Scene) -> int:
    """The contact dimensionality for native mode, from the scene's effects."""
    e = scene.effects
    if e.rolling:
        return 6
    if e.torsional:
        return 4
    return 3 if e.sliding else 1


def mujoco_settings(scene: Scene) -> dict[str, Any]:
    """The keyword arguments of :func:`simulate_mujoco` that the scene asks for."""
    mj = scene.mujoco
    explicit = scene.raw.get("mujoco", {})
    e = scene.effects
    kw: dict[str, Any] = {
        "mode": mj.friction,
        "timestep_s": mj.timestep_s,
        "integrator": mj.integrator,
        "cone": mj.cone,
        "solref": mj.solref,
        "solimp": mj.solimp,
        "impratio": mj.impratio,
        "mu": mj.mu,
    }
    if mj.friction == "paper":
        if e.torsional or e.rolling:
            raise TippetopError("effects: paper mode applies the sliding law only, expected "
                                "torsional = false and rolling = false (use "
                                "mujoco.friction=native), got "
                                f"torsional = {e.torsional}, rolling = {e.rolling}")
        if mj.condim not in (None, 1):
            raise TippetopError(f"mujoco.condim: paper mode needs frictionless contacts, "
                                f"expected 1, got {mj.condim}")
        kw["condim"] = 1
        if "solref" not in explicit:
            kw["solref"] = PAPER_SOLREF
        return kw
    # native: calibrated settings unless the scene names its own
    for key, value in calibrated_native_settings().items():
        if key not in explicit and key in kw:
            kw[key] = value
    kw["condim"] = mj.condim if mj.condim is not None else native_condim(scene)
    if kw["condim"] >= 4:
        kw["torsional"] = (e.torsional_mu if e.torsional_mu is not None
                           else MUJOCO_DEFAULT_TORSIONAL)
    if kw["condim"] == 6:
        kw["rolling"] = e.rolling_mu if e.rolling_mu is not None else MUJOCO_DEFAULT_ROLLING
    if not e.sliding:
        kw["mu"] = 0.0
    return kw


def sample_interval(t_end_s: float, sample_dt_s: float | None, timestep_s: float) -> float:
    """A row spacing that is a whole number of timesteps."""
    dt = sample_dt_s if sample_dt_s is not None else max(DEFAULT_SAMPLE_DT_S, t_end_s / 20_000)
    steps = max(1, round(dt / timestep_s))
    return steps * timestep_s


def run_mujoco(scene: Scene, progress: Callable[[float], None] | None = None) -> EngineRun:
    """Run a scene in MuJoCo and summarise it with the shared metrics."""
    from tippetop.mujoco_runner.model import load_top
    from tippetop.mujoco_runner.run import simulate_mujoco, simulate_top_model

    kw = mujoco_settings(scene)
    sample_dt = sample_interval(scene.run.t_end_s, scene.run.sample_dt_s, kw["timestep_s"])
    if scene.top_mjcf is not None:
        top_model = load_top(scene.top_mjcf)
        top = top_model.top
        res = simulate_top_model(top_model, scene.friction, scene.init,
                                 t_end_s=scene.run.t_end_s, sample_dt_s=sample_dt,
                                 mode=kw["mode"], mu=kw["mu"], progress=progress)
    else:
        top = scene.top
        res = simulate_mujoco(scene.top, scene.friction, scene.init, t_end_s=scene.run.t_end_s,
                              sample_dt_s=sample_dt, progress=progress, **kw)
    if not res.ok:
        # a diverged run is a failed run with its reason, never numbers
        failed = {k: None for k in ("theta_final", "theta_asymp", "t_invert", "J_rel_drift",
                                    "energy_monotone")}
        s = {"engine": "mujoco", **failed, "contact_lost": "contact lost" in res.message,
             "wall_s": res.wall_s, "n_steps": res.n_steps, "status": res.status,
             "message": res.message, "mode": kw["mode"], "timestep_s": kw["timestep_s"],
             "integrator": kw["integrator"], "condim": kw["condim"]}
        return EngineRun(res.table.iloc[:0], s, res.status, res.message)
    s = summary(res.table, engine="mujoco", rtol=MUJOCO_ENERGY_RTOL,
                t_invert=first_inversion_time(res.table), contact_lost=False,
                wall_s=res.wall_s,
                J_scale=jellett_scale(res.table, top.R_m, top.A_kgm2, top.C_kgm2),
                n_steps=res.n_steps)
    s["status"] = res.status
    s["message"] = res.message
    s["mode"] = kw["mode"]
    s["timestep_s"] = kw["timestep_s"]
    s["integrator"] = kw["integrator"]
    s["condim"] = kw["condim"]
    return EngineRun(res.table, s, res.status, res.message)
