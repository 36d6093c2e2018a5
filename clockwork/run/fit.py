"""`clockwork fit`: a scene's parameters from measurements, by weighted
least squares; a sweep run backwards.

Every evaluation of the residuals runs the data file's rows as the points
of a sweep (clockwork.run.batch: the point cache, the FMU instances reused
from one point to the next, the local pool or Dask for many rows): each row
is the scene with that row's parameters set (clockwork.run.fit_data) and
the free parameters at the optimizer's values. The residual of a measured
value y with standard uncertainty s is (model - y) / s (s = 1 where the
file gives none). ``scipy.optimize.least_squares`` (trust region
reflective, the free parameters' declared ranges as bounds) minimises the
sum of their squares, chi2, over the free parameters, each scaled by its
first guess so that a torque of 4e-3 N.m and a Q of 1000 are steps of the
same size to it; the Jacobian is by forward differences at a relative step
of DIFF_STEP.

At the optimum, the columns of the Jacobian are normalised and its
singular values compared with the largest: one below RCOND is a direction
in which the data do not move (a parameter that changes nothing, or two
that change the results only together, as a drive torque and a bob's mass
do); the parameters that take part in it are non-identifiable: named in
one note, their sigma infinite (null in summary.json, with "identifiable":
false). The covariance of the others is the pseudo-inverse of J^T J,
scaled by chi2/dof when the file gives no uncertainties (the scale of the
measurement noise estimated from the residuals).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..analyses.context import reusing_systems
from ..errors import SimulationError, UsageError
from ..results.files import write_csv_atomic, write_json_atomic
from ..results.outdir import OutputDir
from ..version import __version__
from .batch import run_points
from .fit_data import Data, Free

DIFF_STEP = 1e-4  # forward-difference step, relative to each parameter's value
RCOND = 1e-3  # singular values of the column-normalised Jacobian below this, relative to the largest: not identified
NULL_SHARE = 0.1  # a parameter takes part in an unidentified direction where its share of it exceeds this
PENALTY = 1e6  # the residual of a row whose clock stalls or fails at a trial point: a step the optimizer rejects
MAX_EVALUATIONS_PER_PARAMETER = 40


def _scale(f: Free) -> float:
    """What the optimizer's unit step is for `f`: its guess, else the width of its range (else 1)."""
    if f.guess != 0:
        return abs(f.guess)
    width = f.hi - f.lo
    return width if math.isfinite(width) and width > 0 else 1.0


class _Model:
    """The residuals as a function of the scaled free parameters."""

    def __init__(self, scene, data: Data, free: list[Free], workers, scheduler):
        self.scene, self.data, self.free = scene, data, free
        self.workers, self.scheduler = workers, scheduler
        self.columns = list(data.measured)
        y = np.stack([data.measured[c] for c in self.columns], axis=1)  # rows x columns
        self.mask = ~np.isnan(y)
        self.y = y[self.mask]
        if data.sigma:
            s = np.stack([data.sigma[c] for c in self.columns], axis=1)
            self.s = s[self.mask]
        else:
            self.s = np.ones_like(self.y)
        self.scale = np.array([_scale(f) for f in free])
        self.evaluations = 0
        self.points = 0

    def values(self, x: np.ndarray) -> dict:
        return {f.target.key: float(v) for f, v in zip(self.free, x * self.scale)}

    def predict(self, x: np.ndarray) -> tuple[np.ndarray, list[tuple[int, str]]]:
        """The model's value of every measured column per row (nan where it has none) and the rows that failed."""
        free = self.values(x)
        points = [{**row, **free} for row in self.data.settings]
        results = run_points(self.scene, points, self.workers, self.scheduler)
        self.evaluations += 1
        self.points += len(points)
        out = np.full((len(points), len(self.columns)), np.nan)
        failures = []
        for i, r in enumerate(results):
            if "error" in r:
                failures.append((i, str(r["error"])))
                continue
            res = r.get("result", {})
            if res.get("stalled"):
                failures.append((i, f"the clock stalls ({res.get('reason', 'no swing')})"))
                continue
            for j, c in enumerate(self.columns):
                v = res.get(c)
                if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v):
                    out[i, j] = v
                elif self.mask[i, j]:
                    failures.append((i, f"no value of {c}"))
        return out, failures

    def residuals(self, x: np.ndarray) -> np.ndarray:
        model, _ = self.predict(x)
        r = (model[self.mask] - self.y) / self.s
        return np.where(np.isnan(r), PENALTY, r)


def run_fit(scene, data: Data, free: list[Free], out_dir, workers: int | None = None,
            scheduler: str | None = None, command: str = "") -> dict:
    """Fit `free` to `data` and write summary.json, fit.csv and fit.png into
    `out_dir` (whole or not at all: clockwork.results.outdir)."""
    from scipy.optimize import least_squares

    t_start = time.perf_counter()
    model = _Model(scene, data, free, workers, scheduler)
    n_res, n_free = model.y.size, len(free)
    if n_res < n_free or (not data.sigma and n_res == n_free):
        need = "more measured values than" if not data.sigma else "at least as many measured values as"
        raise UsageError(f"{data.path}: {n_res} measured value{'s' * (n_res != 1)} for {n_free} free "
                         f"parameter{'s' * (n_free != 1)}: expected {need} free parameters"
                         f"{' (without sigma_ columns the noise scale comes from the residuals)' if not data.sigma else ''}")
    with OutputDir(out_dir) as out, reusing_systems():
        x0 = np.array([f.guess for f in free]) / model.scale
        lb = np.array([f.lo for f in free]) / model.scale
        ub = np.array([f.hi for f in free]) / model.scale
        max_nfev = MAX_EVALUATIONS_PER_PARAMETER * n_free
        sol = least_squares(model.residuals, x0, bounds=(lb, ub), method="trf", diff_step=DIFF_STEP,
                            max_nfev=max_nfev, x_scale=1.0)
        if sol.status <= 0:
            raise SimulationError(f"the fit did not converge in {model.evaluations} evaluations of the "
                                  f"{data.rows} rows ({sol.message.rstrip('.')}); last values: "
                                  f"{_show_values(free, sol.x * model.scale)}")
        fitted, failures = model.predict(sol.x)
        if failures:
            i, why = failures[0]
            raise SimulationError(f"{data.path}: line {data.lines[i]}: at the fitted values "
                                  f"({_show_values(free, sol.x * model.scale)}) {why}: the fit does not describe "
                                  "this row; check the row or give other guesses")
        summary = _summary(scene, data, free, model, sol, fitted, command)
        _write(out.staging, scene, data, free, model, fitted, summary)
        summary["wall_time_s"] = time.perf_counter() - t_start
        write_json_atomic(out.staging / "summary.json", summary)
        out.commit()
    return summary


def _show_values(free: list[Free], values) -> str:
    return ", ".join(f"{f.name} = {float(v):.6g}{f' {f.target.unit}' if f.target.unit else ''}"
                     for f, v in zip(free, values))


def identify(jac: np.ndarray, scale: np.ndarray) -> tuple[np.ndarray, list[int], np.ndarray]:
    """From the Jacobian `jac` of the residuals with respect to the scaled
    parameters (p = x * scale): the covariance of p (without the residual
    scale) over the identified parameters, the indices of the others, and
    the singular values of the column-normalised Jacobian relative to the
    largest."""
    n = jac.shape[1]
    norms = np.linalg.norm(jac, axis=0)
    dead = [j for j in range(n) if not norms[j] > 0]
    live = [j for j in range(n) if j not in dead]
    cov = np.full((n, n), np.nan)
    relative = np.zeros(n)
    if live:
        jn = jac[:, live] / norms[live]
        _, s, vt = np.linalg.svd(jn, full_matrices=False)
        rel = s / s[0] if s[0] > 0 else np.zeros_like(s)
        relative[: len(rel)] = rel
        keep = rel >= RCOND
        null = vt[~keep]  # rows: directions the data do not see
        unidentified = {live[k] for k in range(len(live)) if null.size and np.max(np.abs(null[:, k])) > NULL_SHARE}
        dead += sorted(unidentified)
        v = vt[keep].T
        cov_z = (v / s[keep] ** 2) @ v.T  # pseudo-inverse of Jn^T Jn
        d = scale[live] / norms[live]
        cov_live = cov_z * np.outer(d, d)
        for a, ja in enumerate(live):
            for b, jb in enumerate(live):
                if ja not in unidentified and jb not in unidentified:
                    cov[ja, jb] = cov_live[a, b]
    return cov, sorted(set(dead)), relative


def _summary(scene, data: Data, free: list[Free], model: _Model, sol, fitted: np.ndarray, command: str) -> dict:
    r = (fitted[model.mask] - model.y) / model.s
    chi2 = float(np.sum(r * r))
    n_res, n_free = model.y.size, len(free)
    dof = n_res - n_free
    cov, unidentified, relative = identify(np.asarray(sol.jac, dtype=float), model.scale)
    scaled = not data.sigma
    factor = chi2 / dof if scaled and dof > 0 else 1.0
    cov = cov * factor
    values = sol.x * model.scale
    sigma = np.sqrt(np.abs(np.diag(cov)))
    parameters = {}
    for j, f in enumerate(free):
        ok = j not in unidentified
        parameters[f.name] = {
            "value": float(values[j]),
            "sigma": float(sigma[j]) if ok else math.inf,  # written as null (strict JSON), "identifiable" says why
            "unit": f.target.unit,
            "identifiable": ok,
            "guess": f.guess,
            "range": [f.lo, f.hi],
            "at_bound": bool(np.isclose(values[j], f.lo, rtol=1e-9, atol=0) or np.isclose(values[j], f.hi, rtol=1e-9, atol=0)),
        }
    correlation = {}
    for a, fa in enumerate(free):
        correlation[fa.name] = {}
        for b, fb in enumerate(free):
            ok = a not in unidentified and b not in unidentified and sigma[a] > 0 and sigma[b] > 0
            correlation[fa.name][fb.name] = float(cov[a, b] / (sigma[a] * sigma[b])) if ok else None
    residuals = []
    for i in range(data.rows):
        row = {"row": i + 1, "line": data.lines[i]}
        if data.labels is not None:
            row["label"] = data.labels[i]
        row["parameters"] = {f"{a}.{b}": v for (a, b), v in data.settings[i].items()}
        for j, c in enumerate(model.columns):
            if not model.mask[i, j]:
                continue
            y = float(data.measured[c][i])
            s = float(data.sigma[c][i]) if data.sigma else None
            row[c] = {"measured": y, "fitted": float(fitted[i, j]), "residual": y - float(fitted[i, j]),
                      "sigma": s, "normalized": (y - float(fitted[i, j])) / s if s else None}
        residuals.append(row)
    notes = []
    if unidentified:
        names = [free[j].name for j in unidentified]
        notes.append(f"not identifiable from these data: {', '.join(names)} (the data do not move "
                     f"{'it' if len(names) == 1 else 'them apart'}: a singular value of the Jacobian below "
                     f"{RCOND:g} of the largest); sigma reported as infinite")
    return {
        "scene": str(scene.path),
        "title": scene.title,
        "tool": {"name": "clockwork", "version": __version__},
        "command": command,
        "fmus": {n: {"file": str(c.fmu_path), "sha256": c.sha256, "model": c.model_description.modelName}
                 for n, c in scene.components.items()},
        "settings": {"master": scene.master.as_dict(), "experiment": asdict(scene.experiment),
                     "analysis": scene.analysis, "overrides": list(scene.overrides)},
        "data": {"file": str(data.path), "sha256": data.sha256, "rows": data.rows,
                 "measured": {c: data.headers[c] for c in model.columns},
                 "negated": [c for c in model.columns if data.signs.get(c, 1.0) < 0],  # a timer's rate: -E_T
                 "set": data.set_columns, "uncertainties": "given" if data.sigma else "from the residuals"},
        "fit": {
            "parameters": parameters,
            "correlation": correlation,
            "chi2": chi2,
            "dof": dof,
            "reduced_chi2": chi2 / dof if dof > 0 else None,
            "sigma_scaled_by_residuals": scaled,
            "residuals": residuals,
            "singular_values_relative": [float(x) for x in relative],
            "evaluations": model.evaluations,
            "points_run": model.points,
            "optimizer": {"method": "least_squares trf", "status": int(sol.status), "message": sol.message,
                          "nfev": int(sol.nfev), "njev": int(sol.njev) if sol.njev is not None else None,
                          "diff_step": DIFF_STEP},
        },
        "notes": notes,
    }


def _write(staging: Path, scene, data: Data, free: list[Free], model: _Model, fitted: np.ndarray,
           summary: dict) -> None:
    header, columns = ["line"], [data.lines]
    if data.labels is not None:
        header.append("label")
        columns.append(data.labels)
    for name in data.set_columns:
        inst, var = _split(name, data)
        header.append(name)
        columns.append([row.get((inst, var)) for row in data.settings])
    for j, c in enumerate(model.columns):
        measured = [None if math.isnan(x) else float(x) for x in data.measured[c]]
        header += [c, f"{c}_fitted", f"{c}_residual"]
        columns += [measured, [float(x) if math.isfinite(x) else None for x in fitted[:, j]],
                    [None if m is None else m - float(fitted[i, j]) for i, m in enumerate(measured)]]
        if data.sigma:
            header.append(f"sigma_{c}")
            columns.append([None if math.isnan(x) else float(x) for x in data.sigma[c]])
    write_csv_atomic(staging / "fit.csv", header, columns)
    files = ["fit.csv"]
    try:
        from ..results.plots.fit import draw_fit
        from ..results.plots.registry import save

        save(draw_fit(scene, summary, model.columns), staging / "fit.png")
        files.append("fit.png")
    except Exception as e:  # the numbers stand without their picture: said in summary.json
        summary["plots_failed"] = [{"file": "fit.png", "kind": "fit", "error": " ".join(str(e).split())}]
    summary["files"] = files + ["summary.json"]


def _split(name: str, data: Data) -> tuple[str, str]:
    """(instance, variable) of a parameter the data file sets."""
    for row in data.settings:
        for key in row:
            if f"{key[0]}.{key[1]}" == name:
                return key
    return tuple(name.rsplit(".", 1))


_DISPLAY = {"rad": ("deg", 180.0 / math.pi), "N.m": ("N.cm", 100.0)}  # as the plots show them


def _in_display_unit(p: dict) -> str:
    """" (= 2.302 +- 0.004 deg)" for a parameter in rad or N.m, else ""."""
    if p["unit"] not in _DISPLAY:
        return ""
    unit, factor = _DISPLAY[p["unit"]]
    sig = f" +- {p['sigma'] * factor:.3g}" if p["identifiable"] else ""
    return f" (= {p['value'] * factor:.6g}{sig} {unit})"


def report_lines(summary: dict, out: Path) -> list[str]:
    """What `clockwork fit` prints: the parameters with their sigmas, chi2, where the files are."""
    fit = summary["fit"]
    lines = [f"{Path(summary['scene']).stem}: fit of {len(fit['parameters'])} parameter"
             f"{'s' * (len(fit['parameters']) != 1)} to {summary['data']['rows']} rows in "
             f"{summary['wall_time_s']:.1f} s ({fit['points_run']} points) -> {out}"]
    for name, p in fit["parameters"].items():
        unit = f" {p['unit']}" if p["unit"] else ""
        sig = f"{p['sigma']:.3g}" if p["identifiable"] else "inf (not identifiable)"
        bound = " (at a bound of its range)" if p["at_bound"] else ""
        shown = _in_display_unit(p)
        lines.append(f"  {name} = {p['value']:.6g} +- {sig}{unit}{shown}{bound}")
    red = fit["reduced_chi2"]
    lines.append(f"  chi2 = {fit['chi2']:.4g}, dof = {fit['dof']}"
                 + (f", chi2/dof = {red:.4g}" if red is not None else "")
                 + (" (sigmas scaled by the residuals)" if fit["sigma_scaled_by_residuals"] else ""))
    lines.append("  files: " + ", ".join(summary["files"]))
    return lines

