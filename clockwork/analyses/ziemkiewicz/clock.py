"""The Ziemkiewicz clock: a pendulum driven by an escapement, at its steady state.

``Clock`` builds a scene's system once and finds steady orbits on it for
any torque (periodic-orbit shooting, clockwork.engine.shooting), a torque
for a wanted amplitude, or the torque of the E_T minimum. The energy
balance of the escapement's work against the damping and drag gives the
shooting's first guess (App. B). ``convert_keys`` checks the analysis keys
that the Ziemkiewicz kinds share.
"""

from __future__ import annotations

import math

from ...engine.shooting import Shooter
from ...errors import SimulationError
from ...physics import analytic
from ...scene.kinds import Invalid
from .. import escapements, keys
from ..context import ESCAPEMENTS, build_system, experiment, find_component, parameters
from ..steady_state import AMPLITUDE_GUESS, MAX_PERIODS, TOLERANCE, SteadyState, find_steady_state

DAY = analytic.SECONDS_PER_DAY
DEG = math.pi / 180.0
# GrasshopperEscapement.profile: the torque's angle profile
PROFILE_NAMES = {0: "constant", 1: "increasing", 2: "decreasing", 3: "Harrison 2/3"}


# The analysis keys the Ziemkiewicz clock kinds share (see docs/scenes.md).
_KICK = ("the kick ends 3 nominal periods 2 pi sqrt(L/g) before experiment.stop (it starts at the first "
         "crossing after kick_time)")
KEYS = {
    "tolerance_s_per_day": TOLERANCE,
    "max_periods": MAX_PERIODS,
    "amplitude_guess": AMPLITUDE_GUESS,
    "amplitude": keys.or_word("optimal", keys.angle_in(0, 150, also="above the GrasshopperEscapement's phi_r, "
                                                                      "which a target amplitude needs")),
    "periods": keys.count(1, keys.MAX_COUNT, also="the values they keep within the 2e7 values bound"),
    "kick_time": keys.duration(0, None, lo_open=False, also=_KICK),
    "kick_duration": keys.duration(0, None, also=_KICK),
    "g_factor": keys.number(0, 1000, also="within the Pendulum FMU's range of g_factor"),
    "kick_at": keys.one_of("zero_crossing", "turning_point"),
}
convert_keys = keys.table_converter(KEYS)


def check_clock(scene, point: dict) -> None:
    """The Ziemkiewicz clock kinds' keys against the scene at a point (what
    Clock and steady_for refuse at run time): a Pendulum, an amplitude
    target only with a GrasshopperEscapement and above its phi_r, and a kick
    inside the experiment."""
    cfg = scene.analysis or {}
    kind = cfg.get("kind", "")
    pendulum = find_component(scene, "Pendulum")
    if pendulum is None:
        raise Invalid("kind", f"a scene with a Pendulum component for {kind}")
    escapement = find_component(scene, ESCAPEMENTS)
    model = scene.components[escapement].model_description.modelName if escapement else None
    params = parameters(scene, point)
    target = cfg.get("amplitude")
    if target is not None and model != "GrasshopperEscapement":
        raise Invalid("amplitude", f"no amplitude target here: {kind} finds the torque for an amplitude of a "
                                   "GrasshopperEscapement, and the scene has none")
    if isinstance(target, float) and target <= params[escapement]["phi_r"]:
        raise Invalid("amplitude", f"an amplitude above the escapement's phi_r = "
                                   f"{math.degrees(params[escapement]['phi_r']):g} deg (a swing must pass it)")
    if kind == "disturbance":
        start, stop = experiment(scene, point)
        pp = params[pendulum]
        T0 = analytic.small_angle_period(pp["L"], pp["g"])
        kick = cfg.get("kick_time", start)
        duration = cfg.get("kick_duration", 1e-3)
        if max(kick, start) + 3.0 * T0 + duration >= stop:
            # The key to change: the duration when the kick alone would fit.
            raise Invalid("kick_duration" if max(kick, start) + 3.0 * T0 < stop else "kick_time",
                          f"a kick that ends 3 nominal periods ({3 * T0:.6g} s) before experiment.stop = {stop:g} s "
                          f"(kick_time {kick:g} s + kick_duration {duration:g} s)")
        g_factor = cfg.get("g_factor", 2.0)
        keys.within_fmu(scene, "g_factor", pendulum, "g_factor", (g_factor, 1.0), "the kick's g_factor")


def escapement_work(esc_model: str, esc: dict, A: float) -> float:
    """Work (J) per period of the escapement on a swing of amplitude A (rad)."""
    return escapements.ESCAPEMENTS[esc_model].work(esc, A)


def loss_per_period(pp: dict, drag: dict | None, A: float) -> float:
    """Energy (J) lost per period on a sinusoidal swing of amplitude A (rad).

    Linear damping I (omega0/Q) w: pi m g L A^2 / Q; drag c1 w: pi c1 omega0 A^2;
    drag c2 w|w|: (8/3) c2 omega0^2 A^3.
    """
    L, m, g, Q = pp["L"], pp["m"], pp["g"], pp["Q"]
    w0 = math.sqrt(g / L)
    loss = math.pi * m * g * L * A * A / Q if Q > 0 else 0.0
    if drag:
        loss += math.pi * drag.get("c1", 0.0) * w0 * A * A + 8.0 / 3.0 * drag.get("c2", 0.0) * w0 * w0 * A**3
    return loss


def energy_balance_guess(pp: dict, esc_model: str | None, esc: dict, drag: dict | None,
                         a_min: float) -> float | None:
    """Amplitude (rad) where the escapement's work balances the losses; a
    shooting start, not a result. None when nothing drives the pendulum."""
    from scipy.optimize import brentq

    if esc_model is None or esc.get("torque", 0.0) <= 0.0:
        return None
    if loss_per_period(pp, drag, 1.0) == 0.0:
        return None

    def f(A):
        return escapement_work(esc_model, esc, A) - loss_per_period(pp, drag, A)

    lo, hi = max(a_min, 1e-6) * (1.0 + 1e-6) + 1e-9, 0.5 * math.pi
    if f(lo) <= 0.0:
        return 1.05 * max(a_min, 1e-3)
    if f(hi) >= 0.0:
        return hi
    return brentq(f, lo, hi, xtol=1e-12)


class Clock:
    """The scene's system and a Shooter: steady orbits for any torque."""

    def __init__(self, scene, point: dict, extra_record: tuple[str, ...] = ()):
        self.scene = scene
        self.pendulum = find_component(scene, "Pendulum")
        if self.pendulum is None:
            raise SimulationError(f"{scene.analysis['kind']}: the scene needs a Pendulum component")
        self.escapement = find_component(scene, ESCAPEMENTS)
        self.drag_name = find_component(scene, "Drag")
        self.params = parameters(scene, point)
        self.pp = self.params[self.pendulum]
        self.esc_model = (scene.components[self.escapement].model_description.modelName
                          if self.escapement else None)
        self.esc = self.params.get(self.escapement, {})
        self.drag = self.params.get(self.drag_name) if self.drag_name else None
        cfg = scene.analysis or {}
        self.tolerance = cfg.get("tolerance_s_per_day", 1e-3) / DAY
        record = {self.pendulum: ["tick_time", "tick_w", "amplitude", *extra_record]}
        self.system = build_system(scene, point, record=record)
        try:
            self.shooter = Shooter(self.system.master, self.params, self.pendulum, self.pp,
                                   max_period_factor=float(cfg.get("max_periods", 3)))
        except BaseException:
            self.system.free()
            raise
        self.T0 = analytic.small_angle_period(self.pp["L"], self.pp["g"])

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.system.free()

    @property
    def a_min(self) -> float | None:
        kind = escapements.escapement(self.esc_model)
        return kind.min_amplitude(self.esc) if kind else None

    @property
    def torque(self) -> float:
        return self.esc["torque"]

    def set_torque(self, torque: float) -> None:
        self.esc["torque"] = torque  # the shooter reads self.params on each map

    def guess(self) -> float | None:
        cfg = self.scene.analysis or {}
        if cfg.get("amplitude_guess"):
            return cfg["amplitude_guess"]
        return energy_balance_guess(self.pp, self.esc_model, self.esc, self.drag, self.a_min or 0.0)

    def steady(self, guess: float | None = None, tolerance: float | None = None) -> SteadyState:
        g = guess if guess is not None else self.guess()
        tol = self.tolerance if tolerance is None else tolerance
        if g is None or g <= 0:
            return SteadyState(stalled=True, tolerance=tol, reason="no driving torque")
        return find_steady_state(self.shooter, g, self.a_min, tolerance=tol)

    def orbit_start(self, st: SteadyState) -> float:
        """W (rad/s) at the upward zero crossing of the converged orbit."""
        # The shooter's last map evaluation is the converged one: its start
        # speed equals its end speed to the residual.
        return self.system.output(self.pendulum, "tick_w")

    # result's keys: the state's, and what the clock adds (some only when not stalled)
    RESULT_COLUMNS = SteadyState.COLUMNS | {"torque_Nm", "E_E_right_s_per_day", "E_E_left_s_per_day",
                                            "E_E_B7_s_per_day", "turns_inside_window", "omitted"}

    def result(self, st: SteadyState) -> dict:
        out = st.as_dict()
        out["torque_Nm"] = self.esc.get("torque")
        if not st.stalled:
            out["E_E_right_s_per_day"] = (st.E_T - analytic.circular_error(st.amplitude_right)) * DAY
            out["E_E_left_s_per_day"] = (st.E_T - analytic.circular_error(st.amplitude_left)) * DAY
            if self.esc_model == "GrasshopperEscapement" and self.pp["Q"] > 0:
                out["E_E_B7_s_per_day"] = analytic.escapement_error_B7(
                    st.amplitude, self.esc["phi_r"], self.pp["Q"]) * DAY
            if self.esc_model == "ChronometerEscapement":
                edge = max(abs(self.esc["alpha_m1"]), abs(self.esc["alpha_m2"]))
                inside = min(st.amplitude_right, st.amplitude_left) < edge
                out["turns_inside_window"] = inside
                if inside:
                    out["omitted"] = True
                    out["reason"] = ("turns inside the impulse window: the end of the impulse at w = 0 "
                                     "is not a located event, and the paper shows no such points")
        out.setdefault("omitted", bool(st.stalled))
        return out

    def torque_for_amplitude(self, target: float, rel_tol: float = 1e-9) -> SteadyState:
        """Solve for the torque whose steady mean amplitude is `target` (rad)."""
        kind = escapements.escapement(self.esc_model)
        if kind is None or not kind.amplitude_target:
            raise SimulationError("an amplitude target needs a GrasshopperEscapement")
        if target <= self.a_min:
            raise SimulationError(f"amplitude {math.degrees(target):g} deg is not above phi_r")
        M1 = analytic.grasshopper_torque_for_amplitude(target, self.esc["phi_r"], self.pp["Q"],
                                                       self.pp["m"], self.pp["L"], self.pp["g"])
        # A grows like sqrt(M) (Eq. B6): secant steps on (ln M, ln A).
        pts: list[tuple[float, float]] = []
        st = None
        x = math.log(M1)
        for _ in range(40):
            self.set_torque(math.exp(x))
            st = self.steady(guess=target if st is None or st.stalled else st.amplitude)
            if st.stalled:
                x += 0.2
                continue
            y = math.log(st.amplitude) - math.log(target)
            if abs(y) < rel_tol:
                return st
            pts.append((x, y))
            if len(pts) >= 2 and pts[-1][1] != pts[-2][1]:
                (x0, y0), (x1, y1) = pts[-2], pts[-1]
                x = x1 - y1 * (x1 - x0) / (y1 - y0)
            else:
                x = x - 2.0 * y
        raise SimulationError(f"no torque found for amplitude {math.degrees(target):g} deg")

    def optimal(self, tolerance: float = 1e-6 / DAY) -> SteadyState:
        """The torque where E_T(A) has its minimum (dE_T/dA = 0)."""
        from scipy.optimize import minimize_scalar

        phi_r = self.esc["phi_r"]
        args = (self.pp["Q"], self.pp["m"], self.pp["L"], self.pp["g"])
        lo = math.log(analytic.grasshopper_torque_for_amplitude(1.2 * phi_r, phi_r, *args))
        hi = math.log(analytic.grasshopper_torque_for_amplitude(min(40 * DEG, 20 * phi_r), phi_r, *args))
        cache: dict[float, SteadyState] = {}

        def f(x):
            self.set_torque(math.exp(x))
            st = self.steady(tolerance=tolerance)
            cache[x] = st
            return math.inf if st.stalled else st.E_T

        res = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": 1e-5})
        self.set_torque(math.exp(res.x))
        st = self.steady(tolerance=tolerance)
        if st.stalled:
            raise SimulationError("no E_T minimum found")
        return st


def steady_for(c: Clock, cfg: dict) -> SteadyState:
    target = cfg.get("amplitude")
    if target == "optimal":
        st = c.optimal()
    elif target is not None:
        st = c.torque_for_amplitude(target)
    else:
        st = c.steady()
    if st.stalled:
        raise SimulationError(f"no steady orbit: {st.reason}")
    return st


def advance_to(master, t_end: float, after_step=None) -> None:
    """Step (events may shorten steps) until exactly t_end."""
    h = master.settings.step
    while master.t < t_end - 1e-13:
        master.step(min(h, t_end - master.t))
        if after_step is not None:
            after_step()


def orbit_rows(results: list[dict]) -> list[dict]:
    """Sweep results that have a usable orbit (not stalled, not omitted)."""
    return [r for r in results if r and "result" in r and not r["result"].get("stalled")
            and not r["result"].get("omitted")]
