"""Diagnostics: tools that explain a figure of the capacity benchmark rather than measure one (why answers come
late, what a host stall or a control query costs). benchmarks/lab/README.md says when each one helps."""
