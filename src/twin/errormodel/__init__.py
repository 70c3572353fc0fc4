"""The paper's comprehensive error model as a small multi-body-system (MBS) engine.

- :mod:`~twin.errormodel.transforms`  4x4 homogeneous matrices, small and exact error matrices
- :mod:`~twin.errormodel.topology`    bodies, the lower-body array, branches (Huston's MBS numbering)
- :mod:`~twin.errormodel.model`       characteristic matrices, full-product and first-order errors, e_z
- :mod:`~twin.errormodel.tester`      the SPB tester's nine bodies from ``tester_topology.toml``
- :mod:`~twin.errormodel.sources`     measured streams -> small-error parameters; which column is which
- :mod:`~twin.errormodel.factors`     the five error factors (thermal, loading, fluctuating,
  positioning, interference) as one list
- :mod:`~twin.errormodel.evaluate`    e_z, its parts and the compensated wear of a signal table
- :mod:`~twin.errormodel.config`      the evaluation's configuration from a scenario or a lab's TOML
- :mod:`~twin.errormodel.credibility` Frechet distance and Ra fluctuation of an on-line wear curve

Pure numpy, vectorised over time series: error parameters and motion variables may be arrays ``(N,)``.
"""

from __future__ import annotations

from twin.errormodel.factors import FACTORS, PARTS, Factor
from twin.errormodel.model import ERROR_KEYS, BranchModel, ErrorModel, Errors, Joint, Motion
from twin.errormodel.tester import load_tester_spec, tester_model
from twin.errormodel.topology import Body, Topology

__all__ = [
    "ERROR_KEYS",
    "FACTORS",
    "PARTS",
    "Body",
    "BranchModel",
    "ErrorModel",
    "Errors",
    "Factor",
    "Joint",
    "Motion",
    "Topology",
    "load_tester_spec",
    "tester_model",
]
