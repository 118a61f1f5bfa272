"""closure_nlp: force-closure grasp and fixture planning on surface elements."""

from . import _quiet_interrupt  # first: a Ctrl-C while the CLI starts is one line
from .contacts import Contact, ContactSet, ContactType, load_contact_set
from .errors import MethodError
from .tolerances import DEFAULT_TOLERANCES, Tolerances

_quiet_interrupt.restore()  # importing the package leaves sys.excepthook as it was

__version__ = "0.1.0"

__all__ = [
    "Contact",
    "ContactSet",
    "ContactType",
    "DEFAULT_TOLERANCES",
    "MethodError",
    "Tolerances",
    "load_contact_set",
]
