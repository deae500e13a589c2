"""`arx`: linear ARX and output-error models, an example of a dynmodel family shipped as its own package."""

from .model import Arx
from .params import ArxParams

__all__ = ["Arx", "ArxParams"]
