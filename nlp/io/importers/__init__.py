"""Finite-element models from other programs, one reader per source.

Each reader returns an :class:`nlp.model.nominal.StructuralModel` with sparse
(``scipy.sparse.csc_matrix``) M0, K0 and influence matrices (Eqns 23-24), and
``dofs``: the (node, dof) of every row, constrained DOFs removed.

opensees   run a user's OpenSeesPy model script, assemble M, K and the
           influence matrices of element groups named in the case
matrices   MAT, NPZ and Matrix Market (.mtx) exports (ABAQUS, ANSYS,
           SAP2000, ...) with a node-to-DOF map
"""

from nlp.io.importers.dofs import DOF_LABELS, dof_number, find_dof, ground_influence
from nlp.io.importers.matrices import load_matrices
from nlp.io.importers.opensees import load_opensees

__all__ = ["DOF_LABELS", "dof_number", "find_dof", "ground_influence", "load_model"]


def load_model(model_cfg, case_path):
    """The StructuralModel of a validated ``model`` section (type opensees or matrices).

    Parameters
    ----------
    model_cfg : nlp.case.schema.ModelConfig
    case_path : str
        The case file, named in input errors.
    """
    if model_cfg.type == "opensees":  # openseespy is imported when the script runs
        return load_opensees(model_cfg, case_path)
    return load_matrices(model_cfg, case_path)
