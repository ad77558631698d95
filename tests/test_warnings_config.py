"""pytest's warning filters (pyproject.toml): a warning raised from frbench's own code fails the run."""

from __future__ import annotations

import warnings

import pytest


def test_a_warning_attributed_to_a_frbench_module_is_an_error_and_others_are_not():
    with pytest.raises(DeprecationWarning, match="a deprecated call"):
        warnings.warn_explicit("a deprecated call", DeprecationWarning, "frbench/policies/x.py", 1,
                               module="frbench.policies.x")
    with pytest.raises(UserWarning, match="at the top"):
        warnings.warn_explicit("at the top", UserWarning, "frbench/__init__.py", 1, module="frbench")
    with pytest.warns(UserWarning, match="elsewhere"):  # another package's warning is only recorded
        warnings.warn_explicit("elsewhere", UserWarning, "frbenchmark.py", 1, module="frbenchmark")
