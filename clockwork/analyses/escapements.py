"""The escapements the analyses know, each by its FMU's modelName.

What an analysis asks of an escapement that depends on which one it is
(the swing it needs, its work per period, its Hoyng quantities, its
averaged twin's settings, its reference model in physics.reference) is
answered here, once per escapement. A new escapement FMU is its model
folder (src_c/models) plus one class here registered in ``ESCAPEMENTS``;
the analyses, the regression kit and the plots find it by its model name.

Parameters are the component's effective values in SI units (context.Parameters).
"""

from __future__ import annotations

import math

DEG = math.pi / 180.0


class Escapement:
    """The contract; every method takes the escapement's parameters `p`."""

    model: str = ""         # the FMU's modelName
    reference: str = ""     # physics.reference.ClockParams.escapement
    twin_kind: int = -1     # AveragedPendulum's `escapement` parameter
    amplitude_target: bool = False  # analyses may solve for the torque of an amplitude

    def min_amplitude(self, p) -> float:
        """The smallest amplitude (rad) of a swing it keeps going."""
        raise NotImplementedError

    def balance_work(self, p) -> float:
        """Work (J) per period at constant torque on a swing past its window."""
        raise NotImplementedError

    def work(self, p, amplitude: float) -> float:
        """Work (J) per period on a swing of this amplitude (rad), its profile included."""
        raise NotImplementedError

    def normalized(self, p, mgl: float) -> dict:
        """Hoyng's normalized escapement quantities (mgl = m g L, J)."""
        raise NotImplementedError

    def twin(self, p) -> dict:
        """AveragedPendulum's escapement parameters that make it this one's twin."""
        raise NotImplementedError

    def drive(self, p, normalized: dict) -> float:
        """AveragedPendulum's drive (N.m) for this escapement."""
        raise NotImplementedError


class Grasshopper(Escapement):
    model, reference, twin_kind, amplitude_target = "GrasshopperEscapement", "grasshopper", 0, True

    def min_amplitude(self, p) -> float:
        return p["phi_r"]

    def balance_work(self, p) -> float:
        return 4.0 * p["torque"] * p["phi_r"]  # Ziemkiewicz App. B, Eq. (B3)

    @staticmethod
    def profile_factor(p, phi: float, recoil: bool) -> float:
        """GrasshopperEscapement's angle profile (see its model description)."""
        kind = int(p.get("profile", 0))
        pa = p.get("profile_angle", 12.0 * DEG)
        if kind == 1:
            return 0.5 + abs(phi) / pa
        if kind == 2:
            return max(0.0, 1.5 - abs(phi) / pa)
        if kind == 3:
            return p.get("harrison_ratio", 2.0 / 3.0) if recoil else 1.0
        return 1.0

    def work(self, p, amplitude: float) -> float:
        from scipy.integrate import quad

        phi_r = p["phi_r"]
        if amplitude <= phi_r:
            return 0.0
        # Moving right: drive from -A up to phi_r, recoil from phi_r to A; the
        # left half swing mirrors it.
        drive = quad(lambda x: self.profile_factor(p, x, False), -amplitude, phi_r, points=[0.0], limit=200)[0]
        recoil = quad(lambda x: self.profile_factor(p, x, True), phi_r, amplitude, limit=200)[0]
        return 2.0 * p["torque"] * (drive - recoil)

    def normalized(self, p, mgl: float) -> dict:
        return {"mu": p["torque"] / mgl, "phi0": p["phi_r"]}

    def twin(self, p) -> dict:
        return {"escapement": self.twin_kind, "phi_r": p["phi_r"]}

    def drive(self, p, normalized: dict) -> float:
        return p["torque"]


class Chronometer(Escapement):
    model, reference, twin_kind = "ChronometerEscapement", "chronometer", 1

    def min_amplitude(self, p) -> float:
        return max(p["alpha_m2"], 0.0)

    def balance_work(self, p) -> float:
        return p["torque"] * (p["alpha_m2"] - p["alpha_m1"])

    def work(self, p, amplitude: float) -> float:
        lo, hi = max(p["alpha_m1"], -amplitude), min(p["alpha_m2"], amplitude)
        return p["torque"] * max(0.0, hi - lo)

    def normalized(self, p, mgl: float) -> dict:
        width = p["alpha_m2"] - p["alpha_m1"]
        return {"e": p["torque"] * width / mgl, "phi1": 0.5 * (p["alpha_m1"] + p["alpha_m2"]), "width": width}

    def twin(self, p) -> dict:
        return {"escapement": self.twin_kind, "phi_1": 0.5 * (p["alpha_m1"] + p["alpha_m2"])}

    def drive(self, p, normalized: dict) -> float:
        return p["torque"] * normalized["width"]


ESCAPEMENTS: dict[str, Escapement] = {e.model: e for e in (Grasshopper(), Chronometer())}
MODELS = tuple(ESCAPEMENTS)
GRASSHOPPER = Grasshopper.model


def escapement(model: str | None) -> Escapement | None:
    """The registered escapement of this modelName, or None."""
    return ESCAPEMENTS.get(model) if model else None
