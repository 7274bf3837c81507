"""The scenarios the scripts of ``diagrams/`` run, as importable code: one module a scenario, each
with its ``build_diagram(...)`` (the control graph), its summary (the figures a run is judged by)
and ``main(argv)`` (the script's command line: build, simulate, summarise, write the run's files;
returns the summary). A script in ``diagrams/`` parses nothing itself: it calls ``main`` and prints
the summary with :func:`sotdrake.simulation.report`. The modules are imported on demand (they pull
in robots, physics, walking), not by ``import sotdrake``.
"""
