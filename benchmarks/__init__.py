"""The benchmarks of mlink-sim: what the simulator achieves on the machine they run on and what it costs, each figure beside
the floor the machine itself allows. Not installed with the package; run from the repository's root, e.g.
``python -m benchmarks.bench --targets``. benchmarks/README.md lists the modules and their commands.

The modules use the public names of :mod:`mlink_sim` only. They start their helper processes as
``python -m benchmarks.…`` with the repository's root on the child's ``PYTHONPATH`` (:func:`benchmarks.common.module_command`).
"""
