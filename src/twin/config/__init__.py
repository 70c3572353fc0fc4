"""Scenario files: read (``load``), checked table by table, into a frozen ``spec.Scenario``.

:mod:`twin.config.load` is the entry point; each scenario table has its own module
(``scenario_table``, ``fmus``, ``connections``, ``inputs``, ``events``), sharing the problem
collector of :mod:`twin.config.reader`. The shipped scenarios are package data
(``twin/config/scenarios/`` when installed, ``scenarios/`` in a checkout).
"""
