"""What the Hoyng analyses share.

Hoyng works in normalized units: time in 1/omega0, friction eps with
phi'' + 2 eps phi' + sin phi = m, torques in units of m g L. The scenes use
L = 1 m, g = 1 m/s2, m = 1 kg, so omega0 = 1 rad/s, a torque in N.m is
Hoyng's mu, Q = 1/(2 eps) and the nominal period is 2 pi s;
``normalized`` converts general L, g, m anyway. An AveragedPendulum in a
scene can be made the pendulum's twin (``twin_values``).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...physics import analytic
from ...errors import SimulationError
from ...scene.kinds import Invalid
from .. import escapements
from ..context import ESCAPEMENTS, find_component, parameters

DAY = analytic.SECONDS_PER_DAY
TWO_PI = 2.0 * math.pi
AVERAGED = "AveragedPendulum"


def normalized(pp: dict, esc_model: str | None = None, ep: dict | None = None) -> dict:
    """Hoyng's normalized quantities from SI parameters."""
    w0 = math.sqrt(pp["g"] / pp["L"])
    mgl = pp["m"] * pp["g"] * pp["L"]
    d = {"w0": w0, "mgl": mgl, "T0": TWO_PI / w0, "eps": 0.5 / pp["Q"] if pp["Q"] > 0 else 0.0}
    kind = escapements.escapement(esc_model)
    if kind is not None:
        d.update(kind.normalized(ep, mgl))
    return d


def second_order(eps: float, circ: float, esc: float) -> float:
    """Size of the rate terms a first-order (KBM) theory leaves out.

    Eqs. (16), (20), (C6) are first order in the small quantities: the
    friction eps, the circular term lambda^2/16 and the escapement term
    (~ mu/lambda). The next order holds their products and squares (e.g.
    lambda^4/384 of Eq. A1, the -eps^2/2 of a damped oscillator), so
    (eps + |circ| + |esc|)^2 bounds it up to a coefficient of order one.
    """
    return (eps + abs(circ) + abs(esc)) ** 2


def hoyng_components(scene):
    pend = find_component(scene, "Pendulum")
    esc = find_component(scene, ESCAPEMENTS)
    avgs = [n for n, c in scene.components.items() if c.model_description.modelName == AVERAGED]
    return pend, esc, avgs


def grasshopper_clock(scene, point: dict, kind: str):
    """(pendulum, escapement, twins, parameters, pendulum's, escapement's,
    normalized) of a scene that must hold a Pendulum and a GrasshopperEscapement."""
    pend, esc, avgs = hoyng_components(scene)
    if pend is None or esc is None or scene.components[esc].model_name != "GrasshopperEscapement":
        raise SimulationError(f"{kind} needs a Pendulum and a GrasshopperEscapement")
    params = parameters(scene, point)
    pp, ep = params[pend], params[esc]
    return pend, esc, avgs, params, pp, ep, normalized(pp, "GrasshopperEscapement", ep)


def check_grasshopper_clock(scene, kind: str) -> None:
    """What grasshopper_clock refuses at run time, as Invalid for validate."""
    pend, esc, _ = hoyng_components(scene)
    if pend is None or esc is None or scene.components[esc].model_name != "GrasshopperEscapement":
        raise Invalid("kind", f"a scene with a Pendulum and a GrasshopperEscapement for {kind}")


def subscene(scene, keep):
    comps = {n: c for n, c in scene.components.items() if n in keep}
    conns = tuple(c for c in scene.connections if c.src_instance in keep and c.dst_instance in keep)
    outs = tuple(o for o in scene.record.outputs if o[0] in keep)
    ticks = scene.record.ticks if scene.record.ticks in keep else None
    rec = dataclasses.replace(scene.record, outputs=outs, ticks=ticks)
    return dataclasses.replace(scene, components=comps, connections=conns, record=rec)


def twin_values(avg: str, pp: dict, esc_model: str | None, ep: dict | None) -> dict:
    """Point entries that make AveragedPendulum `avg` the pendulum's twin."""
    out = {(avg, k): pp[k] for k in ("L", "g", "m", "Q")}
    kind = escapements.escapement(esc_model)
    if kind is not None:
        out.update({(avg, k): v for k, v in kind.twin(ep).items()})
    return out


def linfit(x, y):
    """Least-squares (intercept, slope) of y on x (centred for accuracy)."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if len(x) < 2:
        return math.nan, math.nan
    xm, ym = x.mean(), y.mean()
    dx = x - xm
    slope = float(np.dot(dx, y - ym) / np.dot(dx, dx))
    return float(ym - slope * xm), slope


def escapement_noise(seed: int, rms: float, n: int, chunk: int = 1 << 16) -> np.ndarray:
    """The first n torque deviations delta of GrasshopperEscapement(noise_seed=seed).

    The FMU draws splitmix64 words (state = seed + k * golden gamma, so the
    k-th word needs no loop) and makes one Box-Muller deviate (cosine
    branch) from two words per renewal. Worked in cache-sized chunks with
    in-place operations: 5x faster than whole-array temporaries at the
    4.8e6 renewals of Hoyng Fig. 6.
    """
    out = np.empty(n)
    gamma = np.uint64(0x9E3779B97F4A7C15)
    mix1, mix2 = np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
    s11, s27, s30, s31 = (np.uint64(x) for x in (11, 27, 30, 31))
    base = np.uint64(seed & 0xFFFFFFFF)
    words, shifted = np.empty(2 * chunk, dtype=np.uint64), np.empty(2 * chunk, dtype=np.uint64)
    for i0 in range(0, n, chunk):
        m = min(chunk, n - i0)
        z, tmp = words[:2 * m], shifted[:2 * m]
        z[:] = np.arange(2 * i0 + 1, 2 * (i0 + m) + 1, dtype=np.uint64)
        with np.errstate(over="ignore"):  # splitmix64 wraps modulo 2^64 by design
            np.multiply(z, gamma, out=z)
            np.add(z, base, out=z)
            for shift, mix in ((s30, mix1), (s27, mix2), (s31, None)):
                np.right_shift(z, shift, out=tmp)
                np.bitwise_xor(z, tmp, out=z)
                if mix is not None:
                    np.multiply(z, mix, out=z)
        np.right_shift(z, s11, out=z)
        u = z.astype(float)  # exact: below 2^53
        u1 = (u[0::2] + 1.0) * 2.0**-53
        u2 = u[1::2] * 2.0**-53
        out[i0:i0 + m] = rms * np.sqrt(-2.0 * np.log(u1)) * np.cos(TWO_PI * u2)
    return out


def stationary_rows(results):
    """Sweep results with a co-simulated stationary rate."""
    return [r for r in results if r and "result" in r and not r["result"].get("stalled")
            and r["result"].get("rate_sim") is not None]
