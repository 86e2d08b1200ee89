"""Ensembles as labelled data: the `xarray.Dataset` of an ensemble, and the Zarr store that
`simulate_many(..., store=path)` fills chunk by chunk and `lagrgen.open_ensemble` reopens.

One layout serves both (`layout`): dimensions run × state × time (plus `constraint`, `output` and
`sensitivity`),
the states named like the coordinates then `<coordinate>_dot`, one variable per parameter over
`run` (named `param_<name>` where the name is taken by a variable of the layout), `success`,
`status` and `nfev` per run, units in attrs. xarray and Zarr are the `ensembles` extra and are
imported here only.
"""
import json
import zlib

import numpy as np

from .errors import StoreError, StoreWarning

#: Variables and coordinates of the layout (a parameter of one of these names gets a prefix).
RESERVED = ("y", "success", "status", "nfev", "multipliers", "outputs", "run", "state", "time",
            "constraint", "output", "chunk_written", "chunk_crc32", "chunk", "chunk_array",
            "transition", "transition_run", "transition_time", "transition_element",
            "transition_kind", "sensitivities", "sensitivity")
FORMAT = "lagrgen-ensemble-2"
#: The formats `open_ensemble` reads (1: before the chunk records).
FORMATS = ("lagrgen-ensemble-1", FORMAT)
#: The per-run arrays a chunk of runs writes, in the order of its checksums.
PER_RUN = ("y", "success", "status", "nfev", "multipliers", "outputs", "sensitivities")
#: The chunk records: a flag set once a chunk is written whole, and the CRC-32 of each of its
#: per-run arrays as stored (0 for one the store lacks).
CHUNK_WRITTEN, CHUNK_CRC32 = "chunk_written", "chunk_crc32"
#: The group of a model with impacts or frictions that holds, per chunk of runs, the table of
#: its runs' transitions: rows (run, t, element index, kind index).
TRANSITIONS = "transitions"


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
    names = meta.get("sensitivity_names", ())
    if names:
        coords["sensitivity"] = (("sensitivity",), np.array(names, dtype=str), {})
        big["sensitivities"] = (("run", "sensitivity", "state", "time"),
                                (runs, len(names), len(states), k), "f8",
                                {"long_name": "forward sensitivities d y(t) / d p_j of the "
                                              "parameters (or initial states y0:<state>) named"})
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
            "sensitivity_names": tuple(ens.sensitivity_names)
            if ens.sensitivities is not None else (),
            "units": dict(ens.units), "method": "", "rtol": float("nan"), "atol": float("nan"),
            **ens.settings}
    coords, small, big, attrs = layout(meta, ens.runs)
    values = {"y": ens.y, "success": ens.success, "status": ens.status, "nfev": ens.nfev,
              "multipliers": ens.multipliers, "outputs": ens.outputs,
              "sensitivities": ens.sensitivities}
    data = {name: (dims, v, a) for name, (dims, v, a) in small.items()}
    for name, (dims, shape, dtype, a) in big.items():
        data[name] = (dims, np.asarray(values[name]).astype(dtype, copy=False), a)
    if ens.transitions is not None:
        rows = [(run, t, name, kind) for run, listed in enumerate(ens.transitions)
                for t, name, kind in listed or ()]
        data.update(transition_variables(*(list(column) for column in zip(*rows))
                                         if rows else ([], [], [], [])))
    return xr.Dataset(data, coords=coords, attrs=attrs)


def transition_variables(runs, times, elements, kinds):
    """The transitions of every run as a table over the dimension `transition` (run by run, in
    time order): `transition_run`, `transition_time`, `transition_element`, `transition_kind`."""
    dims = ("transition",)
    return {"transition_run": (dims, np.asarray(runs, dtype="i8"), {"long_name": "run index"}),
            "transition_time": (dims, np.asarray(times, dtype=float),
                                {"long_name": "time of the switch", "units": "s"}),
            "transition_element": (dims, np.asarray(elements, dtype=str),
                                   {"long_name": "impact or friction"}),
            "transition_kind": (dims, np.asarray(kinds, dtype=str),
                                {"long_name": "impact, contact, release, stick or slip"})}


def local_store(path, read_only=False):
    """The Zarr store of the directory `path`, opened as a local store: never a string that
    zarr hands to fsspec (which reads `::` as a chain of URLs and `~` literally)."""
    import zarr
    if hasattr(zarr.storage, "LocalStore"):          # Zarr 3
        return zarr.storage.LocalStore(str(path), read_only=read_only)
    return zarr.storage.DirectoryStore(str(path))     # Zarr 2


def create_store(path, meta, runs, chunk):
    """A new Zarr store at `path` (replacing one there) holding the layout: labels and
    parameters written, the per-run arrays created empty (NaN) with `chunk` runs per chunk, and
    the chunk records (`CHUNK_WRITTEN`, `CHUNK_CRC32`, see `write_part`)."""
    xr = _xarray()
    import zarr
    refuse_foreign(path)
    coords, small, big, attrs = layout(meta, runs)
    skeleton = xr.Dataset({name: (dims, v, a) for name, (dims, v, a) in small.items()},
                          coords=coords, attrs=dict(attrs, complete=False))
    try:        # Zarr format 2: the format every Zarr reader knows (strings, consolidation)
        skeleton.to_zarr(local_store(path), mode="w", consolidated=False, zarr_format=2)
    except TypeError:       # xarray before 2024.10 (Zarr 2) writes format 2 without being asked
        skeleton.to_zarr(local_store(path), mode="w", consolidated=False)
    group = zarr.open_group(local_store(path), mode="r+")
    chunks = -(-runs // chunk)
    records = {CHUNK_WRITTEN: (("chunk",), (chunks,), (1,), "u1", {}),
               CHUNK_CRC32: (("chunk", "chunk_array"), (chunks, len(PER_RUN)), (1, len(PER_RUN)),
                             "u4", {"arrays": list(PER_RUN)})}
    for name, (dims, shape, dtype, a) in big.items():
        records[name] = (dims, shape, (chunk,) + tuple(shape[1:]), dtype, a)
    for name, (dims, shape, chunks_of, dtype, a) in records.items():
        fill = np.nan if dtype == "f8" else None     # None: integers and flags are not masked
        _create(group, name, shape, chunks_of, dtype, fill, dict(a, _ARRAY_DIMENSIONS=list(dims)))
    if meta.get("elements"):         # a model with impacts or frictions: one table per chunk
        from .hybrid import KIND_NAMES
        group.create_group(TRANSITIONS).attrs.update(
            {"elements": list(meta["elements"]), "kinds": list(KIND_NAMES)})
    zarr.consolidate_metadata(local_store(path))


def store_path(store):
    """The store as an absolute local path, `~` expanded (Dask workers may run elsewhere in the
    file system); TypeError for anything but a local path."""
    import os
    if not isinstance(store, (str, os.PathLike)) or "://" in os.fspath(store):
        raise TypeError(f"store must be a local path (str or pathlib.Path), not {store!r}")
    return os.path.abspath(os.path.expanduser(os.fspath(store)))


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
        found = zarr.open_group(local_store(path, read_only=True), mode="r").attrs
        if found.get("lagrgen_format") in FORMATS:
            return
    except Exception:
        pass
    raise FileExistsError(f"{path} exists and is not an ensemble store of lagrgen: choose a new "
                          "path (an ensemble store there would be replaced)")


def _checksums(arrays, dtypes):
    """CRC-32 of each per-run array of one chunk, as stored (0 for an array the store lacks)."""
    return np.array([zlib.crc32(np.ascontiguousarray(arrays[name], dtype=dtypes[name]).data)
                     if name in dtypes else 0 for name in PER_RUN], dtype=np.uint32)


def write_part(path, start, result):
    """Write one chunk's arrays (rows start .. start + m) into the store, then its checksums,
    then its completion flag (so that a flag set means the chunk was written whole)."""
    import zarr
    group = zarr.open_group(local_store(path), mode="r+")
    m = len(result["status"])
    dtypes = {name: group[name].dtype for name in PER_RUN if name in group}
    for name in dtypes:
        _every_chunk(group[name])[start:start + m] = result[name]
    k = start // group["status"].chunks[0]
    if TRANSITIONS in group and result.get("transitions") is not None:
        table = group[TRANSITIONS]
        element = {name: j for j, name in enumerate(table.attrs["elements"])}
        kind = {name: j for j, name in enumerate(table.attrs["kinds"])}
        rows = np.array([(start + i, t, element[name], kind[what])
                         for i, listed in enumerate(result["transitions"])
                         for t, name, what in listed or ()], dtype=float).reshape(-1, 4)
        _create(table, f"chunk{k}", rows.shape, (max(len(rows), 1), 4), "f8")[:] = rows
    if CHUNK_WRITTEN in group:
        _every_chunk(group[CHUNK_CRC32])[k] = _checksums(result, dtypes)
        _every_chunk(group[CHUNK_WRITTEN])[k] = 1


def _create(group, name, shape, chunks, dtype, fill=None, attrs=None):
    """A new array of `group` (Zarr 3's create_array or Zarr 2's create_dataset)."""
    if hasattr(group, "create_array"):
        return group.create_array(name, shape=shape, chunks=chunks, dtype=dtype,
                                  fill_value=fill, attributes=attrs or {})
    array = group.create_dataset(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill)
    array.attrs.update(attrs or {})
    return array


def _every_chunk(array):
    """`array` writing every chunk, also one that holds only its fill value (Zarr 3 skips those
    by default; a missing chunk file then marks damage)."""
    return array.with_config({"write_empty_chunks": True}) if hasattr(array, "with_config") \
        else array


def finish_store(path, messages):
    """Mark the store complete (every chunk written), keep the messages of the runs that did not
    end normally ({run: message}), and consolidate its metadata."""
    import zarr
    group = zarr.open_group(local_store(path), mode="r+")
    group.attrs.update({"complete": True, "messages": dict(messages)})
    zarr.consolidate_metadata(local_store(path))


def open_ensemble(store, verify=True):
    """Reopen an ensemble written by `simulate_many(..., store=path)` as an `xarray.Dataset`
    that reads lazily (Dask arrays, one chunk per written chunk, when Dask is installed).

    Every chunk of runs is checked against the records written with it: a chunk whose files
    are missing, or (with `verify`) whose data no longer match their CRC-32 or cannot be
    decoded, is damaged. Its runs read as failed — `success` False, `status` −3, NaN states —
    are listed in `attrs["damaged"]` ({first run: reason}) and reported in a `StoreWarning`;
    runs never written (an interrupted ensemble) read as not run (status −2).

    Parameters
    ----------
    store : path (str or pathlib.Path; `~` expanded) of the Zarr store
    verify : True (default) reads every chunk once to check its CRC-32; False checks only that
        every chunk's files are there (a quick check for very large stores)

    Returns
    -------
    xarray.Dataset, laid out as `EnsembleResult.to_xarray()`; `attrs["complete"]` is False when
    the run that wrote it was interrupted

    Raises
    ------
    FileNotFoundError when there is no store; StoreError when it is not a readable ensemble
    store (damaged metadata, missing arrays)
    """
    xr = _xarray()
    import os
    path = store_path(store)
    if not os.path.exists(path):
        raise FileNotFoundError(f"no ensemble store at {os.fspath(store)!r}")
    try:
        import dask  # noqa: F401
        chunks = {}
    except ImportError:
        chunks = None
    try:
        ds = xr.open_zarr(local_store(path, read_only=True), chunks=chunks, consolidated=True)
    except Exception as exc:
        raise StoreError(f"{path} cannot be read as an ensemble store ({type(exc).__name__}: "
                         f"{exc}); it is damaged or not a store of lagrgen.simulate_many") \
            from None
    if ds.attrs.get("lagrgen_format") not in FORMATS:
        raise StoreError(f"{path!r} is not an ensemble store written by lagrgen.simulate_many")
    if CHUNK_WRITTEN not in ds:
        return ds                                   # a store of format 1: no chunk records
    try:
        group = consolidated_group(path)
        health = chunk_health(path, group, ds, verify)
        chunk = int(group["status"].chunks[0])
    except Exception as exc:
        raise StoreError(f"{path}: its chunk records cannot be read ({type(exc).__name__}: "
                         f"{exc}); the store is damaged") from None
    ds = ds.drop_vars([CHUNK_WRITTEN, CHUNK_CRC32])
    if TRANSITIONS in group:            # its chunk tables are made as chunks finish: unlisted
        import zarr                     # in the metadata consolidated when the store was made
        table = zarr.open_group(local_store(path, read_only=True), mode="r", path=TRANSITIONS)
        ds = ds.assign(stored_transitions(table, health))
    return marked(ds, health, chunk, path)


def stored_transitions(table, health):
    """`transition_variables` of the chunk tables of a store, but those of chunks in `health`
    (not written, damaged)."""
    elements, kinds = table.attrs["elements"], table.attrs["kinds"]
    names = sorted((name for name in table.array_keys()
                    if int(name[len("chunk"):]) not in health), key=lambda n: int(n[5:]))
    rows = np.concatenate([np.asarray(table[name][:]).reshape(-1, 4) for name in names]) \
        if names else np.zeros((0, 4))
    return transition_variables(rows[:, 0].astype(int), rows[:, 1],
                                [elements[int(j)] for j in rows[:, 2]],
                                [kinds[int(j)] for j in rows[:, 3]])


def consolidated_group(path):
    """The store's group read through its consolidated metadata (so that an array whose own
    metadata file is gone is still known, and its missing chunks found)."""
    import zarr
    if hasattr(zarr.storage, "LocalStore"):
        return zarr.open_group(local_store(path, read_only=True), mode="r",
                               use_consolidated=True)
    return zarr.open_consolidated(local_store(path), mode="r")


def chunk_health(path, group, ds, verify):
    """{chunk index: "not written" or why it is damaged} for every chunk that is not whole."""
    import os
    chunk = int(group["status"].chunks[0])
    runs = ds.sizes["run"]
    written = np.asarray(group[CHUNK_WRITTEN][:])
    crc = np.asarray(group[CHUNK_CRC32][:])
    present = {name: group[name] for name in PER_RUN if name in ds}
    health = {}
    for k in range(len(written)):
        if not written[k]:
            health[k] = "not written"
            continue
        for name, array in present.items():
            key = ".".join([str(k)] + ["0"] * (array.ndim - 1))
            if not os.path.isfile(os.path.join(path, name, key)):
                health[k] = f"the chunk file {name}/{key} is missing"
                break
            if not verify:
                continue
            try:
                data = array[k * chunk:min((k + 1) * chunk, runs)]
            except Exception as exc:
                health[k] = f"{name}/{key} cannot be decoded ({type(exc).__name__})"
                break
            if zlib.crc32(np.ascontiguousarray(data).data) != crc[k, PER_RUN.index(name)]:
                health[k] = f"{name}/{key} does not match its checksum"
                break
    return health


def marked(ds, health, chunk, path):
    """`ds` with the runs of the chunks in `health` read as not run (status −2) or damaged
    (−3): success False, states NaN, nothing read from a damaged chunk."""
    if not health:
        return ds
    import warnings
    runs = ds.sizes["run"]
    status = np.zeros(runs, dtype="i4")
    success = np.zeros(runs, dtype=bool)
    nfev = np.zeros(runs, dtype="i8")
    bad = np.zeros(runs, dtype=bool)
    for k in range(-(-runs // chunk)):
        rows = slice(k * chunk, min((k + 1) * chunk, runs))
        if k in health:
            bad[rows] = True
            status[rows] = -2 if health[k] == "not written" else -3
        else:                                      # a whole chunk: its small arrays as written
            status[rows] = ds["status"][rows].values
            success[rows] = ds["success"][rows].values
            nfev[rows] = ds["nfev"][rows].values
    out = ds.copy()
    for name, values in (("status", status), ("success", success), ("nfev", nfev)):
        out[name] = (ds[name].dims, values, ds[name].attrs)
    for name in ("y", "multipliers", "outputs", "sensitivities"):
        if name in ds:
            out[name] = (ds[name].dims, _without(ds[name].data, bad, chunk), ds[name].attrs)
    damaged = {str(k * chunk): reason for k, reason in sorted(health.items())
               if reason != "not written"}
    if damaged:
        out.attrs["damaged"] = damaged
        listing = "; ".join(f"{_runs(int(first), min(int(first) + chunk, runs) - 1)}: {why}"
                            for first, why in damaged.items())
        warnings.warn(f"ensemble store {path}: {listing}. These runs read as failed "
                      "(success False, status -3, states NaN).", StoreWarning, stacklevel=3)
    return out


def _runs(first, last):
    return f"run {first}" if first == last else f"runs {first}–{last}"


def _without(data, bad, chunk):
    """The array `data` (run first; Dask or NumPy) with the rows of `bad` chunks NaN, built so
    that those chunks are never read."""
    runs = data.shape[0]
    if type(data).__module__.startswith("dask"):
        import dask.array as da
        blocks = []
        for a in range(0, runs, chunk):
            piece = data[a:min(a + chunk, runs)]
            blocks.append(da.full(piece.shape, np.nan, chunks=piece.shape) if bad[a] else piece)
        return da.concatenate(blocks, axis=0)
    out = np.full(data.shape, np.nan)
    for a in range(0, runs, chunk):
        if not bad[a]:
            out[a:min(a + chunk, runs)] = np.asarray(data[a:min(a + chunk, runs)])
    return out
