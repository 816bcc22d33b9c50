"""scikit-learn's parameter protocol without importing scikit-learn.

:class:`Params` gives an estimator whose ``__init__`` stores each parameter unchanged under its
own name ``get_params``, ``set_params`` and a repr of the parameters that differ from their
defaults, as ``sklearn.base.BaseEstimator`` does; ``sklearn.base.clone`` takes any object with
``get_params``. For estimators that the command line imports on its quick paths (Algorithm 1 in
``articulation fit``): importing ``sklearn.base`` costs 0.7-1.3 s, ten times the module itself.
"""

from __future__ import annotations

import inspect

from artmotion.errors import InputError

__all__ = ["Params"]


class Params:
    """``get_params``/``set_params``/``__repr__`` from the ``__init__`` signature."""

    @classmethod
    def _param_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return sorted(p.name for p in sig.parameters.values()
                      if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD))

    def get_params(self, deep: bool = True) -> dict:
        """The parameters as given (``deep`` is accepted for scikit-learn; none is an estimator)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """The parameters changed, by making the estimator anew with them (its constructor checks
        them; a refused one leaves the estimator as it was when the constructor checks before it
        sets anything); an unknown name is an :class:`InputError`."""
        known = self._param_names()
        unknown = sorted(set(params) - set(known))
        if unknown:
            raise InputError(f"set_params: {', '.join(map(repr, unknown))} is not a parameter of "
                             f"{type(self).__name__} (its parameters: {', '.join(known)})")
        type(self).__init__(self, **{**self.get_params(), **params})
        return self

    def __repr__(self) -> str:
        defaults = {p.name: p.default for p in inspect.signature(type(self).__init__).parameters.values()}
        shown = []
        for name, value in self.get_params().items():
            default = defaults.get(name, inspect.Parameter.empty)
            try:
                same = value is default or bool(value == default)
            except (TypeError, ValueError):      # (arrays compare element-wise)
                same = False
            if not same:
                shown.append(f"{name}={value!r}")
        return f"{type(self).__name__}({', '.join(shown)})"
