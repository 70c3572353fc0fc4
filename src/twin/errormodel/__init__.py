"""The paper's comprehensive error model as a small multi-body-system (MBS) engine.

- :mod:`~twin.errormodel.transforms`  4x4 homogeneous matrices, small and exact error matrices
- :mod:`~twin.errormodel.topology`    bodies, the lower-body array, branches (Huston's MBS numbering)
- :mod:`~twin.errormodel.model`       characteristic matrices, full-product and first-order errors, e_z
- :mod:`~twin.errormodel.tester`      the SPB tester's nine bodies from ``tester_topology.toml``

Pure numpy, vectorised over time series: error parameters and motion variables may be arrays ``(N,)``.
"""

from __future__ import annotations

from twin.errormodel.model import ERROR_KEYS, BranchModel, ErrorModel, Errors, Joint, Motion
from twin.errormodel.tester import load_tester_spec, tester_model
from twin.errormodel.topology import Body, Topology

__all__ = [
    "ERROR_KEYS",
    "Body",
    "BranchModel",
    "ErrorModel",
    "Errors",
    "Joint",
    "Motion",
    "Topology",
    "load_tester_spec",
    "tester_model",
]
