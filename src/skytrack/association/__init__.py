"""Association: sparse candidate search, the spec-000 gate, global nearest neighbour."""

from skytrack.association.candidates import candidate_pairs, max_eigenvalue_sym
from skytrack.association.gnn import assign_gnn

__all__ = ["assign_gnn", "candidate_pairs", "max_eigenvalue_sym"]
