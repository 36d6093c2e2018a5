"""The regression kit: cases for other FMI tools (export-suite) and the grading of their results (compare).

See docs/regression-kit.md."""
