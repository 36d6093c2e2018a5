"""The FMI layer: everything about reading and calling FMUs.

Below the engine and knowing nothing of it: the archive and its cache
(``archive``), the model description and its checks (``description``,
``description_check``, ``types``), the variables as the master sees them
(``variables``), what every face's calls share (``calls``: status codes,
logging, the crash guard), the ctypes mirrors of the compiled core's structs
(``layout``), the instance contract the master uses (``contract``) and
the faces behind it, one module per FMI version and interface: ``cs1``,
``cs2`` and ``cs3`` for Co-Simulation, ``me2`` and ``me3`` for Model
Exchange (the engine's wrapper composes them with its integrator), and
``values3`` for the values of every FMI 3.0 type.

Importing this package imports nothing else: the plot process reads
``types`` without fmpy or lxml.
"""
