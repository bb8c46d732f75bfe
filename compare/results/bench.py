"""``tippetop bench ode``'s result: the reference's kernel against its peers and scipy."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

#: The issue's target: the compiled integrator at least this many times faster than scipy.
TARGET_SPEEDUP = 60.0
#: ... with the final theta agreeing to this (rad).
TARGET_THETA_AGREEMENT = 1e-6
#: A peer is "of equal accuracy" when its final theta agrees with tippetop's to this (rad).
EQUAL_ACCURACY_RAD = 1e-10
#: The target against the fastest peer of equal accuracy (peer time / tippetop time), and
#: the moonshot.
TARGET_VS_PEER = 1.0
MOONSHOT_VS_PEER = 1.2
#: scipy's name in the report.
SCIPY = "scipy solve_ivp(DOP853)"


@dataclass(frozen=True)
class BenchOdeResult:
    """The Fig. 11 top integrated by the reference's default method, its peers and scipy.

    The fields are the keys of ``tippetop bench ode --json``, in its order.

    Attributes:
        n0: Initial spin (rad/s).
        t_end_s: Simulated time (s).
        rtol: Relative tolerance asked.
        atol: Absolute tolerance asked.
        method: The method the default (``auto``) runs at ``rtol``.
        method_rtol: The rtol it runs at.
        method_atol: The atol it runs at.
        timing: How the times are measured.
        rounds: Rounds in which the solvers take turns.
        scipy_rounds: Of those, the rounds scipy runs in.
        ours_s: The whole :func:`simulate_ode` call's best CPU time (s).
        ours_n_rhs: Its right-hand side evaluations.
        ours_kernel_s: The kernel's best CPU time (s), the baseline.
        ours_kernel_n_rhs: Its evaluations (a Taylor method's: its jets).
        theta_final_kernel: The kernel's theta(t_end) (rad).
        scipy_s: scipy's best CPU time (s).
        scipy_n_rhs: Its evaluations.
        speedup: ``scipy_s / ours_s``.
        theta_final_ours: simulate_ode's theta(t_end) (rad).
        theta_final_scipy: scipy's theta(t_end) (rad).
        theta_final_abs_diff: |theta_final_ours - theta_final_scipy| (rad).
        ours_ns_per_rhs: ns per evaluation of simulate_ode's whole call.
        scipy_ns_per_rhs: ns per evaluation of scipy's.
        target_speedup_met: ``speedup >= TARGET_SPEEDUP``.
        target_theta_met: ``theta_final_abs_diff <= TARGET_THETA_AGREEMENT``.
        peers: ``available`` and, without the peers, ``reason``; with them ``solvers`` (per
            peer its run at ``rtol``, its sweep and its time at our error),
            ``equal_accuracy_rad``, ``best_equal_accuracy``, ``not_equal_accuracy``,
            ``theta_truth``, ``truth_rtol``, ``ours_theta_err`` and ``equal_error``.
        speedup_vs_best_peer: The fastest peer's time at our error over ``ours_kernel_s``
            (None: no peer reaches it, or no peer ran).
        best_peer: That peer (or None).
        target_vs_peer_met: ``speedup_vs_best_peer >= TARGET_VS_PEER`` (None without it).
        report: The printed report (the JSON has always carried it).
    """

    n0: float
    t_end_s: float
    rtol: float
    atol: float
    method: str
    method_rtol: float
    method_atol: float
    timing: str
    rounds: int
    scipy_rounds: int
    ours_s: float
    ours_n_rhs: int
    ours_kernel_s: float
    ours_kernel_n_rhs: int
    theta_final_kernel: float
    scipy_s: float
    scipy_n_rhs: int
    speedup: float
    theta_final_ours: float
    theta_final_scipy: float
    theta_final_abs_diff: float
    ours_ns_per_rhs: float
    scipy_ns_per_rhs: float
    target_speedup_met: bool
    target_theta_met: bool
    peers: dict[str, Any]
    speedup_vs_best_peer: float | None
    best_peer: str | None
    target_vs_peer_met: bool | None
    report: str = ""

    @property
    def ours(self) -> str:
        """The kernel's name in the report: ``tippetop <method>``."""
        return f"tippetop {self.method}"

    def to_json(self) -> dict[str, Any]:
        """What ``tippetop bench ode --json`` prints: every field, ``report`` last."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> BenchOdeResult:
        """A result read back from its JSON."""
        return cls(**{f.name: data[f.name] for f in fields(cls)})


__all__ = ["EQUAL_ACCURACY_RAD", "MOONSHOT_VS_PEER", "SCIPY", "TARGET_SPEEDUP",
           "TARGET_THETA_AGREEMENT", "TARGET_VS_PEER", "BenchOdeResult"]
