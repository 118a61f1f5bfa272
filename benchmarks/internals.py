"""The internal pieces that the benchmarks and ``examples/compare_solvers.py`` time one by one:
the search without its certificate, the certificate alone, the conic cross-checks, the random
suite. They are not the public API (``closure_nlp``'s top level) and may move; this module is
the one place outside the package that names them."""

from closure_nlp.base.files import write_atomic
from closure_nlp.contact.random_sets import BENCH_CASES, random_contact_set
from closure_nlp.contact.wrenches import WrenchSlots
from closure_nlp.criterion.certificate import certified_bounds
from closure_nlp.criterion.crosscheck import ball_minimum, force_closure_check
from closure_nlp.criterion.support_minimum import SupportMinimizer, certified_rho, search_rho

__all__ = [
    "BENCH_CASES",
    "SupportMinimizer",
    "WrenchSlots",
    "ball_minimum",
    "certified_bounds",
    "certified_rho",
    "force_closure_check",
    "random_contact_set",
    "search_rho",
    "write_atomic",
]
