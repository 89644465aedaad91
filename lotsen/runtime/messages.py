"""Re-export of the message types (they live in `lotsen.messages`, below every subpackage)."""

from lotsen.messages import *  # noqa: F401,F403
from lotsen.messages import __all__  # noqa: F401
