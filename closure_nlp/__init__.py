"""closure_nlp: force-closure grasp and fixture planning on surface elements.

The names below are the public API; every other module is internal and may move. They load on
first use, so that ``import closure_nlp`` (and the command line's start) stays light.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from closure_nlp.base import quiet_interrupt as _quiet_interrupt  # first: Ctrl-C is one line

_quiet_interrupt.restore()  # importing the package leaves sys.excepthook as it was

from closure_nlp._version import __version__  # noqa: E402

# public name -> module that defines it
_PUBLIC = {
    # contact sets
    "Contact": "closure_nlp.contact.contact_set",
    "ContactSet": "closure_nlp.contact.contact_set",
    "ContactType": "closure_nlp.contact.contact_set",
    "ContactSpec": "closure_nlp.contact.contact_set",
    "load_contact_set": "closure_nlp.contact.contact_set",
    "ModelTolerance": "closure_nlp.contact.accuracy",
    # models
    "Element": "closure_nlp.model.elements",
    "ElementKind": "closure_nlp.model.elements",
    "Model": "closure_nlp.model.elements",
    "load_model": "closure_nlp.model.elements",
    "save_model": "closure_nlp.model.elements",
    "contact_specs": "closure_nlp.model.scale",
    "characterize": "closure_nlp.model.characterize",
    "characterize_mesh": "closure_nlp.model.characterize",
    "drop_outward_as_read": "closure_nlp.model.characterize",
    "CharacterizeOptions": "closure_nlp.model.characterize",
    # rho and rho_hat
    "rho": "closure_nlp.criterion.support_minimum",
    "RhoResult": "closure_nlp.criterion.support_minimum",
    "SearchOptions": "closure_nlp.criterion.support_minimum",
    "Eligibility": "closure_nlp.criterion.rho_hat",
    "EligibilityResult": "closure_nlp.criterion.rho_hat",
    "eligibility": "closure_nlp.criterion.rho_hat",
    "force_closure_cvxpy": "closure_nlp.criterion.crosscheck",
    "distance_cvxpy": "closure_nlp.criterion.crosscheck",
    # loads the part must hold
    "Loads": "closure_nlp.contact.loads",
    "load_loads": "closure_nlp.contact.loads",
    "LoadFactor": "closure_nlp.criterion.load_factor",
    "LoadFactors": "closure_nlp.criterion.load_factor",
    "load_factors": "closure_nlp.criterion.load_factor",
    "load_factor_cvxpy": "closure_nlp.criterion.crosscheck",
    "warm_up": "closure_nlp.criterion.warm_up",
    "rho_many": "closure_nlp.criterion.many",
    "RhoColumns": "closure_nlp.criterion.many",
    "rho_hat_many": "closure_nlp.criterion.many",
    "RhoHatColumns": "closure_nlp.criterion.many",
    # selection, placement, planning, reports
    "select": "closure_nlp.selection.algorithms",
    "heuristic": "closure_nlp.selection.algorithms",
    "iterative": "closure_nlp.selection.algorithms",
    "SelectionOptions": "closure_nlp.selection.algorithms",
    "SelectionResult": "closure_nlp.selection.algorithms",
    "place": "closure_nlp.placement.place",
    "Placer": "closure_nlp.placement.place",
    "PlacementOptions": "closure_nlp.placement.placer",
    "PlacementResult": "closure_nlp.placement.placer",
    "plan": "closure_nlp.planning.plan",
    "PlanResult": "closure_nlp.planning.single",
    "write_report": "closure_nlp.report.plan_report",
    # studies (grids of plans on Dask)
    "Study": "closure_nlp.study.grid",
    "load_study": "closure_nlp.study.grid",
    "study_from_dict": "closure_nlp.study.grid",
    "run_study": "closure_nlp.study.running",
    "local_cluster": "closure_nlp.study.running",
    # numerics and errors
    "Tolerances": "closure_nlp.base.tolerances",
    "DEFAULT_TOLERANCES": "closure_nlp.base.tolerances",
    "MethodError": "closure_nlp.base.errors",
}

__all__ = [
    "__version__",
    "CharacterizeOptions",
    "Contact",
    "ContactSet",
    "ContactSpec",
    "ContactType",
    "DEFAULT_TOLERANCES",
    "Element",
    "ElementKind",
    "Eligibility",
    "EligibilityResult",
    "LoadFactor",
    "LoadFactors",
    "Loads",
    "MethodError",
    "Model",
    "ModelTolerance",
    "PlacementOptions",
    "PlacementResult",
    "Placer",
    "PlanResult",
    "RhoColumns",
    "RhoHatColumns",
    "RhoResult",
    "SearchOptions",
    "SelectionOptions",
    "SelectionResult",
    "Study",
    "Tolerances",
    "characterize",
    "characterize_mesh",
    "contact_specs",
    "distance_cvxpy",
    "drop_outward_as_read",
    "eligibility",
    "force_closure_cvxpy",
    "heuristic",
    "iterative",
    "load_contact_set",
    "load_factor_cvxpy",
    "load_factors",
    "load_loads",
    "load_model",
    "load_study",
    "local_cluster",
    "place",
    "plan",
    "rho",
    "rho_hat_many",
    "rho_many",
    "run_study",
    "save_model",
    "select",
    "study_from_dict",
    "warm_up",
    "write_report",
]


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module 'closure_nlp' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))


if TYPE_CHECKING:  # what static tools see; at run time the names load on first use
    from closure_nlp.base.errors import MethodError
    from closure_nlp.base.tolerances import DEFAULT_TOLERANCES, Tolerances
    from closure_nlp.contact.accuracy import ModelTolerance
    from closure_nlp.contact.contact_set import (
        Contact,
        ContactSet,
        ContactSpec,
        ContactType,
        load_contact_set,
    )
    from closure_nlp.contact.loads import Loads, load_loads
    from closure_nlp.criterion.crosscheck import (
        distance_cvxpy,
        force_closure_cvxpy,
        load_factor_cvxpy,
    )
    from closure_nlp.criterion.load_factor import LoadFactor, LoadFactors, load_factors
    from closure_nlp.criterion.many import RhoColumns, RhoHatColumns, rho_hat_many, rho_many
    from closure_nlp.criterion.rho_hat import Eligibility, EligibilityResult, eligibility
    from closure_nlp.criterion.support_minimum import RhoResult, SearchOptions, rho
    from closure_nlp.criterion.warm_up import warm_up
    from closure_nlp.model.characterize import (
        CharacterizeOptions,
        characterize,
        characterize_mesh,
        drop_outward_as_read,
    )
    from closure_nlp.model.elements import Element, ElementKind, Model, load_model, save_model
    from closure_nlp.model.scale import contact_specs
    from closure_nlp.placement.place import Placer, place
    from closure_nlp.placement.placer import PlacementOptions, PlacementResult
    from closure_nlp.planning.plan import plan
    from closure_nlp.planning.single import PlanResult
    from closure_nlp.report.plan_report import write_report
    from closure_nlp.selection.algorithms import (
        SelectionOptions,
        SelectionResult,
        heuristic,
        iterative,
        select,
    )
    from closure_nlp.study.grid import Study, load_study, study_from_dict
    from closure_nlp.study.running import local_cluster, run_study
