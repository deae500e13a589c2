"""Built-in data generators: the systems the thesis experiments on, with its parameter values.

* ``linear-system``   y_t = a0 y_{t-1} + b0 u_t, u ~ N(0, 1)                      (eq. 3.19)
* ``driven-logistic`` y_t = (1 - alpha) lambda y_{t-1} (1 - y_{t-1}) + alpha u_t,
                      u ~ U[0, 1]                                                  (eq. 3.34)
* ``narx-system``     y_t = a0 y_{t-1} + b0 / (1 + |y_{t-2}|) + c0 u_t, u ~ N(0, 1)  (eq. 3.37 / 5.47)
* ``rossler-cross``   Rossler system, input z1(t), output z2(t + T)                 (eq. 4.54)
* ``rossler-lorenz``  Rossler drives Lorenz through u = x1 + x2 + x3, output z1      (eq. 5.53 / 5.54)
"""

from .flows import RosslerCross, RosslerLorenz
from .maps import DrivenLogistic, LinearSystem, NarxSystem

__all__ = ["LinearSystem", "DrivenLogistic", "NarxSystem", "RosslerCross", "RosslerLorenz"]
