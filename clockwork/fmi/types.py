"""The FMI variable types by family, without the description's reader: what
the plot process needs to tell text, integers and reals apart, imported
without fmpy and lxml (its start-up time; results.plots.background)."""

# The integer types and their ranges (FMI 2.0's Integer, FMI 3.0's sized ones).
INT_RANGES = {"Integer": (-2**31, 2**31 - 1), "Int32": (-2**31, 2**31 - 1),
              **{f"Int{b}": (-2**(b - 1), 2**(b - 1) - 1) for b in (8, 16, 64)},
              **{f"UInt{b}": (0, 2**b - 1) for b in (8, 16, 32, 64)}}
INTEGER_TYPES = (*INT_RANGES, "Enumeration")
# Float32 is a Real exchanged through fmi3Get/SetFloat32.
REAL_TYPES = ("Real", "Float32")
# Recorded as text: Binary as hexadecimal digits (FMI 3.0).
TEXT_TYPES = ("String", "Binary")
