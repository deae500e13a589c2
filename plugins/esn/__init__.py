"""The `esn` family: echo state networks, internal and external approach (thesis 5.2.3, 5.3.2)."""

from .model import EchoStateNetwork
from .params import EsnParams

__all__ = ["EchoStateNetwork", "EsnParams"]
