"""A fitted GP law as named arrays and JSON metadata, and back, checking every entry.

The file (``.npz``, kind ``gp_law``) holds the standardisation, the hyperparameters, the mean
function's coefficients and the posterior's arrays (:data:`~.gp_posterior.FITTED_ARRAYS`); the
metadata the estimator's parameters, the modes and sizes, and what the fit measured. Models that
embed a GP (the inverse model) store the same entries under a prefix of their own.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import InvalidInput, Problem
from .gp_posterior import FITTED_ARRAYS, MODES

KIND = "gp_law"
VERSION = 2                     # 2: linear_coef (the mean function) stored


def law_to_arrays(law: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """The fitted ``law`` (a :class:`~.gp.GPLaw`) as named arrays and JSON metadata."""
    arrays = {"x_mean": law.x_mean_, "x_scale": law.x_scale_, "y_mean": law.y_mean_,
              "y_scale": law.y_scale_, "length_scale": law.length_scale_,
              "hyper": np.array([law.sigma_f_, law.noise_]), "linear_coef": law.linear_coef_}
    for key, attr in FITTED_ARRAYS.items():
        value = getattr(law, attr)
        if value is not None:
            arrays[key] = value
    params = {k: (list(v) if isinstance(v, (tuple, np.ndarray)) else v) for k, v in law.get_params().items()
              if not (k == "theta" and v is None) and not (k == "subset_noise" and not v)
              and not (k == "hyper_subsets" and v == 1) and k != "n_jobs"}
    # (files without fixed hyperparameters, subset noise or hyperparameter subsets read as before and by
    # earlier versions; n_jobs says where a fit ran, not what it is)
    meta = {"params": params, "mode": law.mode_, "var_mode": law.var_mode_,
            "n_train": int(law.n_train_), "n_features": int(law.n_features_in_),
            "n_outputs": int(law.n_outputs_), "y_1d": bool(law.y_1d_),
            "n_inducing": 0 if law.inducing_ is None else int(law.inducing_.shape[0]),
            "n_hyper_used": int(law.n_hyper_used_),
            "log_marginal_likelihood": law.log_marginal_likelihood_,
            "heldout_nrmse": None if law.heldout_nrmse_ is None else list(map(float, law.heldout_nrmse_)),
            "fit_seconds": law.fit_seconds_, "summary": law.summary()}
    return arrays, meta


def law_from_arrays(cls: type, arrays: dict[str, np.ndarray], meta: dict[str, Any], file: str,
                    prefix: str = "") -> Any:
    """Inverse of :func:`law_to_arrays`: a law of class ``cls`` with every fitted attribute set (its
    prediction path not yet built); problems name ``file`` and the entry (under ``prefix``)."""
    def fail(element: str, msg: str) -> InvalidInput:
        return InvalidInput(msg, file=file, element=prefix + element)

    try:
        params = dict(meta["params"])
        mode, var_mode = meta["mode"], meta["var_mode"]
        n, d, p = int(meta["n_train"]), int(meta["n_features"]), int(meta["n_outputs"])
        m = int(meta["n_inducing"])
    except (KeyError, TypeError, ValueError) as exc:
        raise fail("meta", f"metadata entry missing or malformed ({exc})") from None
    if mode not in MODES:
        raise fail("meta.mode", f"unknown mode {mode!r}; known: {', '.join(MODES)}")
    if var_mode not in MODES or (mode == "sparse" and var_mode != "sparse"):
        raise fail("meta.var_mode", f"invalid variance mode {var_mode!r} for mode {mode!r}")
    if min(n, d, p) < 1 or m < 0 or (var_mode == "sparse" and m < 1):
        raise fail("meta", f"bad sizes n_train={n}, n_features={d}, n_outputs={p}, n_inducing={m}")
    try:
        law = cls(**params)
    except TypeError as exc:
        raise fail("meta.params", f"unknown estimator parameter ({exc})") from None
    expected = _expected_shapes(mode, var_mode, n, d, p, m)
    _check_arrays(arrays, expected, file, prefix, f"(n_train={n}, n_features={d}, n_outputs={p}, n_inducing={m})",
                  mode)
    f64 = {k: np.ascontiguousarray(v, dtype=np.float64) for k, v in arrays.items() if k in expected}
    law.x_mean_, law.x_scale_ = f64["x_mean"], f64["x_scale"]
    law.y_mean_, law.y_scale_ = f64["y_mean"], f64["y_scale"]
    law.length_scale_ = f64["length_scale"]
    law.linear_coef_ = f64["linear_coef"]
    law.sigma_f_, law.noise_ = float(f64["hyper"][0]), float(f64["hyper"][1])
    for key, attr in FITTED_ARRAYS.items():
        setattr(law, attr, f64.get(key))
    if law.chol_ is not None:
        law.chol_ = np.asfortranarray(law.chol_)
    law.mode_, law.var_mode_ = mode, var_mode
    law.n_train_, law.n_features_in_, law.n_outputs_ = n, d, p
    law.y_1d_ = bool(meta.get("y_1d", False)) and p == 1
    law.n_hyper_used_ = int(meta.get("n_hyper_used", min(n, law.n_hyper)))
    law.log_marginal_likelihood_ = meta.get("log_marginal_likelihood")
    h = meta.get("heldout_nrmse")
    law.heldout_nrmse_ = None if h is None else np.asarray(h, dtype=np.float64)
    law.fit_seconds_ = meta.get("fit_seconds")
    return law


def _expected_shapes(mode: str, var_mode: str, n: int, d: int, p: int, m: int) -> dict[str, tuple[int, ...]]:
    """The arrays a law of these modes and sizes must hold, with their shapes."""
    expected: dict[str, tuple[int, ...]] = {
        "x_mean": (d,), "x_scale": (d,), "y_mean": (p,), "y_scale": (p,), "length_scale": (d,), "hyper": (2,),
        "linear_coef": (d + 1, p)}
    if mode == "exact":
        expected.update(Z=(n, d), alpha=(n, p))
    if var_mode == "exact":
        expected.update(chol=(n, n))
    if var_mode == "sparse":
        expected.update(inducing=(m, d), beta=(m, p), sparse_M=(m, m))
    return expected


def _check_arrays(arrays: dict[str, np.ndarray], expected: dict[str, tuple[int, ...]], file: str, prefix: str,
                  sizes: str, mode: str) -> None:
    """Every expected array present, numeric, of its shape and finite; scales positive. Raises one
    :class:`InvalidInput` listing every problem."""
    problems = []
    for key, shape in expected.items():
        if key not in arrays:
            problems.append(Problem(file, prefix + key, f"array is missing (needed by mode {mode!r})"))
            continue
        a = arrays[key]
        if a.dtype.kind not in "fiu":
            problems.append(Problem(file, prefix + key, f"has dtype {a.dtype}, expected float numbers"))
        elif a.shape != shape:
            problems.append(Problem(file, prefix + key, f"has shape {a.shape}, expected {shape} {sizes}"))
        elif not np.all(np.isfinite(a)):
            problems.append(Problem(file, prefix + key, "has non-finite values"))
    if not problems:
        for key in ("x_scale", "y_scale", "length_scale", "hyper"):
            if np.any(arrays[key] <= 0):
                problems.append(Problem(file, prefix + key, "must be positive"))
    if problems:
        raise InvalidInput(problems)
