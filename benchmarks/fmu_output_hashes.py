"""Hash the outputs of a driven run of each of the six original FMUs, to
show that a change to the models leaves their results bit for bit.

    python benchmarks/fmu_output_hashes.py fmus              # after the change
    python benchmarks/fmu_output_hashes.py /path/to/old/fmus # before it

Each FMU runs with fmpy for 4 s (the AveragedPendulum 400 s), its inputs
driven by phi(t), w(t) and a1(t) where it has them; one sha256 (first 16
hex digits) of every output column, per FMU.
"""
import hashlib, sys
import numpy as np
from fmpy import simulate_fmu, read_model_description
fmudir = sys.argv[1]
t = np.linspace(0.0, 4.0, 401)
sig = np.array(list(zip(t, 0.2 * np.sin(3.1 * t), 0.6 * np.cos(3.1 * t), 0.003 * np.sin(1.3 * t))),
               dtype=[("time", float), ("phi", float), ("w", float), ("a1", float)])
for name in ["Pendulum", "GrasshopperEscapement", "ChronometerEscapement", "Drag", "MechanismVibration", "AveragedPendulum"]:
    path = f"{fmudir}/{name}.fmu"
    md = read_model_description(path)
    ins = [v.name for v in md.modelVariables if v.causality == "input"]
    outs = [v.name for v in md.modelVariables if v.causality == "output"]
    cols = [c for c in ("phi", "w", "a1") if c in ins]
    inp = None
    if cols:
        inp = np.array(list(zip(t, *[sig[c] for c in cols])), dtype=[("time", float)] + [(c, float) for c in cols])
    start = {}
    if name == "Pendulum":
        start = {"phi_start": 0.2, "Q": 300.0, "tau_external": 0.01}
    if name == "Drag":
        start = {"c1": 1e-3, "c2": 2e-3}
    stop = 4.0 if name != "AveragedPendulum" else 400.0
    r = simulate_fmu(path, stop_time=stop, output_interval=stop / 400, start_values=start, input=inp, output=outs)
    h = hashlib.sha256(b"".join(np.ascontiguousarray(r[c]).tobytes() for c in outs)).hexdigest()
    print(name, len(r), h[:16])
