"""Independent verification of planned trajectories.

Deliberately shares nothing with the transcription: it re-integrates each aircraft from its initial
state under the planned controls (the dynamics model's own right-hand side, by a fixed-step Runge-Kutta
method of order 6 on the plan's control samples, all aircraft at once; see :func:`fly`), samples the flown
trajectory densely and checks the airspace, the exact obstacle geometry (and every crossing of a gate plane), the
separation of every pair of airborne aircraft, the load factors and the bank angle, the gate and runway
conditions (their headings are ground tracks: in a scenario's wind the flown, air-relative heading must be the
crabbed one; the flown track is reported too). ``verified`` is True only when every check holds.

The safety minima (airspace, obstacles, the hole, separation, load factors, bank angle) allow NO tolerance
on the unsafe side. The flown trajectory is known at dense samples; between them the true path departs
from the straight chord by at most ``dt^2/8 * a_max`` (a_max: the largest acceleration the load-factor
limits allow), and that bound is added on the safe side: obstacles are inflated by it, the separation
and the airspace are required with it to spare. The published controls are linear between their
samples (that is how :func:`fly` flies them), so checking the samples against the (convex) limits is
exact. Tolerances apply only to accuracy: how closely the flown path matches the published one, and how
closely it meets the runway and gate attitudes and positions.
"""


from mal_planner.verification.check import verify
from mal_planner.verification.flight import fly, fly_all, fly_reference
from mal_planner.verification.report import AircraftCheck, LandingGap, PairCheck, Tolerances, VerificationReport
from mal_planner.verification.separation import separation_checks
from mal_planner.verification.space import chord_error_bound, flown_path_infringements

__all__ = [
    "AircraftCheck",
    "LandingGap",
    "PairCheck",
    "Tolerances",
    "VerificationReport",
    "chord_error_bound",
    "flown_path_infringements",
    "fly",
    "fly_all",
    "fly_reference",
    "separation_checks",
    "verify",
]
