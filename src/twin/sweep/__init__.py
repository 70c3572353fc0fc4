"""Sweeps, Monte Carlo and sensitivity analysis of scenarios on Dask distributed (``twin sweep``).

A sweep file names a base scenario and a design over the values a study varies
(:mod:`~twin.sweep.spec`); the design's points and seeds are drawn on the client
(:mod:`~twin.sweep.design`), each point a checked copy of the base scenario; each is prepared
and run in memory on a Dask worker (:mod:`twin.pipeline.point`, :mod:`twin.pipeline.cluster`)
with the client's binaries shipped to it (:mod:`twin.pipeline.shipping`); the results table
grows on disk as points finish (:mod:`twin.pipeline.results`, :mod:`~twin.sweep.runner`) and
ends with quantiles, SALib's indices (:mod:`~twin.sweep.analysis`) and figures
(:mod:`~twin.sweep.plots`).
"""
