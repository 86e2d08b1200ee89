"""Ensembles as labelled data: the `xarray.Dataset` of an ensemble, and the Zarr store that
`simulate_many(..., store=path)` fills chunk by chunk and `lagrgen.open_ensemble` reopens.

One layout serves both (`layout`): dimensions run × state × time (plus `constraint` and `output`),
the states named like the coordinates then `<coordinate>_dot`, one variable per parameter over
`run` (named `param_<name>` where the name is taken by a variable of the layout), `success`,
`status` and `nfev` per run, units in attrs. xarray and Zarr are the `ensembles` extra and are
imported here only.
"""
import json

import numpy as np

#: Variables and coordinates of the layout (a parameter of one of these names gets a prefix).
RESERVED = ("y", "success", "status", "nfev", "multipliers", "outputs", "run", "state", "time",
            "constraint", "output")
FORMAT = "lagrgen-ensemble-1"


def parameter_variable(name):
    """The Dataset variable that holds parameter `name` per run."""
    return f"param_{name}" if name in RESERVED else name


def _rate_unit(unit):
    if not unit:
        return ""
    return f"({unit})/s" if "/" in unit else f"{unit}/s"


def layout(meta, runs):
    """(coords, small variables, big variables, attrs) of an ensemble's Dataset.

    coords : {name: (dims, values, attrs)}; small: {name: (dims, values, attrs)} known before
    any run (the parameters); big: {name: (dims, shape, dtype, attrs)} filled run by run.
    """
    units = meta["units"]
    k = len(meta["t"])
    states = meta["states"]
    n = len(meta["coordinates"])
    state_units = [units.get(c, "") or "" for c in meta["coordinates"]]
    state_units += [_rate_unit(u) for u in state_units[:n]]
    coords = {"run": (("run",), np.arange(runs), {"long_name": "run index"}),
              "state": (("state",), np.array(states, dtype=str), {"units": state_units}),
              "time": (("time",), np.asarray(meta["t"], dtype=float), {"units": "s"})}
    small = {}
    for j, name in enumerate(meta["parameters"]):
        small[parameter_variable(name)] = (("run",), np.asarray(meta["params"])[:, j],
                                           {"long_name": f"parameter {name}",
                                            "units": units.get(name, "") or ""})
    big = {"y": (("run", "state", "time"), (runs, len(states), k), "f8",
                 {"long_name": "state [q, q_dot] at the output times",
                  "state_units": state_units}),
           "success": (("run",), (runs,), "bool", {"long_name": "the run reached its end"}),
           "status": (("run",), (runs,), "i4",
                      {"long_name": "solve_ivp status: 0 reached the end, 1 terminal event, "
                                    "-1 failure"}),
           "nfev": (("run",), (runs,), "i8", {"long_name": "right-hand side evaluations"})}
    if meta["constraint_names"]:
        coords["constraint"] = (("constraint",), np.array(meta["constraint_names"], dtype=str),
                                {})
        big["multipliers"] = (("run", "constraint", "time"),
                              (runs, len(meta["constraint_names"]), k), "f8",
                              {"long_name": "constraint forces lambda (M qdd = F + A^T lambda)"})
    if meta["output_names"]:
        out_units = [units.get(o, "") or "" for o in meta["output_names"]]
        coords["output"] = (("output",), np.array(meta["output_names"], dtype=str),
                            {"units": out_units})
        big["outputs"] = (("run", "output", "time"), (runs, len(meta["output_names"]), k), "f8",
                          {"long_name": "model outputs", "output_units": out_units})
    attrs = {"model": meta["model"], "method": meta["method"], "rtol": meta["rtol"],
             "atol": meta["atol"], "units": json.dumps(units), "lagrgen_format": FORMAT,
             "coordinates_q": list(meta["coordinates"]), "parameters": list(meta["parameters"])}
    return coords, small, big, attrs


def _xarray():
    try:
        import xarray
    except ImportError as exc:
        raise ImportError("labelled ensemble results need xarray (and a store needs zarr): "
                          "pip install 'lagrgen[ensembles]'") from exc
    return xarray


def to_dataset(ens):
    """The in-memory `xarray.Dataset` of an EnsembleResult (see `EnsembleResult.to_xarray`)."""
    xr = _xarray()
    meta = {"model": ens.model_name, "coordinates": tuple(ens.coordinates),
            "states": tuple(ens.coordinates) + tuple(f"{c}_dot" for c in ens.coordinates),
            "parameters": tuple(ens.parameter_names), "params": ens.params, "t": ens.t,
            "output_names": tuple(ens.output_names) if ens.outputs is not None else (),
            "constraint_names": tuple(ens.constraint_names)
            if ens.multipliers is not None else (),
            "units": dict(ens.units), "method": "", "rtol": float("nan"), "atol": float("nan"),
            **ens.settings}
    coords, small, big, attrs = layout(meta, ens.runs)
    values = {"y": ens.y, "success": ens.success, "status": ens.status, "nfev": ens.nfev,
              "multipliers": ens.multipliers, "outputs": ens.outputs}
    data = {name: (dims, v, a) for name, (dims, v, a) in small.items()}
    for name, (dims, shape, dtype, a) in big.items():
        data[name] = (dims, np.asarray(values[name]).astype(dtype, copy=False), a)
    return xr.Dataset(data, coords=coords, attrs=attrs)


def create_store(path, meta, runs, chunk):
    """A new Zarr store at `path` (replacing one there) holding the layout: labels and
    parameters written, the per-run arrays created empty (NaN) with `chunk` runs per chunk."""
    xr = _xarray()
    import zarr
    refuse_foreign(path)
    coords, small, big, attrs = layout(meta, runs)
    skeleton = xr.Dataset({name: (dims, v, a) for name, (dims, v, a) in small.items()},
                          coords=coords, attrs=dict(attrs, complete=False))
    try:        # Zarr format 2: the format every Zarr reader knows (strings, consolidation)
        skeleton.to_zarr(str(path), mode="w", consolidated=False, zarr_format=2)
    except TypeError:       # xarray before 2024.10 (Zarr 2) writes format 2 without being asked
        skeleton.to_zarr(str(path), mode="w", consolidated=False)
    group = zarr.open_group(str(path), mode="r+")
    for name, (dims, shape, dtype, a) in big.items():
        chunks = (chunk,) + tuple(shape[1:])
        fill = np.nan if dtype == "f8" else None     # None: integers and flags are not masked
        attrs = dict(a, _ARRAY_DIMENSIONS=list(dims))
        if hasattr(group, "create_array"):
            group.create_array(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill,
                               attributes=attrs)
        else:
            group.create_dataset(name, shape=shape, chunks=chunks, dtype=dtype,
                                 fill_value=fill).attrs.update(attrs)
    zarr.consolidate_metadata(str(path))


def store_path(store):
    """The store as an absolute path (Dask workers may run elsewhere in the file system)."""
    import os
    if not isinstance(store, (str, os.PathLike)) or "://" in str(store):
        raise TypeError(f"store must be a local path (str or pathlib.Path), not {store!r}")
    return os.path.abspath(os.fspath(store))


def refuse_foreign(path):
    """FileExistsError when `path` holds something other than an ensemble store (which a new
    ensemble replaces)."""
    import os
    if not os.path.exists(path):
        return
    if os.path.isdir(path) and not os.listdir(path):
        return
    try:
        import zarr
        if zarr.open_group(path, mode="r").attrs.get("lagrgen_format") == FORMAT:
            return
    except Exception:
        pass
    raise FileExistsError(f"{path} exists and is not an ensemble store of lagrgen: choose a new "
                          "path (an ensemble store there would be replaced)")


def write_part(path, start, result):
    """Write one chunk's arrays (rows start .. start + m) into the store."""
    import zarr
    group = zarr.open_group(str(path), mode="r+")
    m = len(result["status"])
    for name in ("y", "success", "status", "nfev", "multipliers", "outputs"):
        if name in result and name in group:
            group[name][start:start + m] = result[name]


def finish_store(path, messages):
    """Mark the store complete (every chunk written), keep the messages of the runs that did not
    end normally ({run: message}), and consolidate its metadata."""
    import zarr
    group = zarr.open_group(str(path), mode="r+")
    group.attrs.update({"complete": True, "messages": dict(messages)})
    zarr.consolidate_metadata(str(path))


def open_ensemble(store):
    """Reopen an ensemble written by `simulate_many(..., store=path)` as an `xarray.Dataset`
    that reads lazily (Dask arrays, one chunk per written chunk, when Dask is installed).

    Parameters
    ----------
    store : path (str or pathlib.Path) of the Zarr store, or any store xarray.open_zarr takes

    Returns
    -------
    xarray.Dataset, laid out as `EnsembleResult.to_xarray()`; `attrs["complete"]` is False when
    the run that wrote it was interrupted (the runs not written read as NaN, status 0)
    """
    xr = _xarray()
    import os
    if isinstance(store, (str, os.PathLike)) and not os.path.exists(store):
        raise FileNotFoundError(f"no ensemble store at {store!r}")
    try:
        import dask  # noqa: F401
        chunks = {}
    except ImportError:
        chunks = None
    ds = xr.open_zarr(store, chunks=chunks, consolidated=True)
    if ds.attrs.get("lagrgen_format") != FORMAT:
        raise ValueError(f"{store!r} is not an ensemble store written by lagrgen.simulate_many")
    return ds
