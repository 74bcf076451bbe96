"""HDF5 tables via ``h5py``.

The table is located by the option ``dataset`` (an HDF5 path such as
``/imu`` or ``/sensors/imu0``), or found automatically. Three shapes are read:

* a **compound** dataset (one record per sample, one field per column, as
  written by pandas/PyTables ``format="table"`` or numpy structured arrays);
* a **group** of equally long 1-D datasets, one per column;
* a **2-D** numeric dataset whose ``columns`` attribute names its columns.

Column names are recognised exactly as in CSV files (``time_s``,
``gyro_x_dps``, ``accel_x_g``, EuRoC/Kalibr names, ...), and a ``unit``
attribute on a 1-D dataset is used when its name states no unit.
Only the needed columns are read from disk.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from imubounds.errors import ImuboundsError, InputError
from imubounds.io.log import ImuLog

from .assemble import ReadOptions, assemble_logs
from .columns import plan_columns
from .table import _raw_from_arrays


def _attr_text(v: Any) -> str:
    return v.decode() if isinstance(v, bytes) else str(v)


def _candidates(f: Any) -> list[str]:
    """HDF5 paths that look like tables (compound, 2-D with columns, groups of 1-D)."""
    import h5py

    out: list[str] = []

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Dataset):
            if obj.dtype.names or (obj.ndim == 2 and "columns" in obj.attrs):
                out.append("/" + name)
        elif isinstance(obj, h5py.Group):
            one_d = [k for k, v in obj.items() if isinstance(v, h5py.Dataset) and v.ndim == 1
                     and v.dtype.kind in "fiu"]
            if len(one_d) >= 2:
                out.append("/" + name)

    f.visititems(visit)
    root_1d = [k for k, v in f.items() if isinstance(v, h5py.Dataset) and v.ndim == 1
               and v.dtype.kind in "fiu"]
    if len(root_1d) >= 2:
        out.insert(0, "/")
    return out


def read_hdf5(path: Path, opts: ReadOptions) -> list[ImuLog]:
    """Read an IMU table from an HDF5 file into SI :class:`ImuLog` segment(s).

    Parameters
    ----------
    path:
        ``.h5``/``.hdf5``/``.hdf`` file.
    opts:
        Reader options; ``opts.extra["dataset"]`` is the HDF5 path of the
        table (default: the only table-like object in the file).
    """
    import h5py

    try:
        f = h5py.File(path, "r")
    except (OSError, ValueError) as err:
        raise InputError(
            f"{path}: not a readable HDF5 file ({' '.join(str(err).split())[:120]}); "
            "check that it was written completely"
        ) from err
    with f:
        wanted = opts.extra.get("dataset")
        if wanted is not None:
            key = str(wanted)
            if key not in f:
                have = _candidates(f)
                raise InputError(
                    f"{path}: no dataset or group {key!r}; table-like objects in the file: "
                    f"{', '.join(have) if have else 'none'}; give one with --dataset"
                )
        else:
            have = _candidates(f)
            if not have:
                raise InputError(
                    f"{path}: no IMU table found (a compound dataset, a 2-D dataset with a "
                    "'columns' attribute, or a group of 1-D datasets); give one with --dataset"
                )
            if len(have) > 1:
                raise InputError(
                    f"{path}: several tables ({', '.join(have)}); choose one with --dataset"
                )
            key = have[0]
        try:
            return _read_table(path, f[key], key, opts)
        except ImuboundsError:
            raise
        except (OSError, ValueError, KeyError) as err:
            raise InputError(
                f"{path}:{key}: cannot read the data ({' '.join(str(err).split())[:120]}); "
                "the file is probably truncated or corrupt"
            ) from err


def _read_table(path: Path, obj: Any, key: str, opts: ReadOptions) -> list[ImuLog]:
    import h5py

    src = f"{path}:{key}"
    units: dict[str, str] = {}
    if isinstance(obj, h5py.Group):
        names = [k for k, v in obj.items() if isinstance(v, h5py.Dataset) and v.ndim == 1]
        for k in names:
            if "unit" in obj[k].attrs:
                units[k] = _attr_text(obj[k].attrs["unit"])
        header = [_with_unit(k, units.get(k)) for k in names]

        def get(i: int) -> np.ndarray:
            return np.asarray(obj[names[i]][()])
    elif obj.dtype.names:
        names = list(obj.dtype.names)
        header = names

        def get(i: int) -> np.ndarray:
            return np.asarray(obj.fields(names[i])[()])
    elif obj.ndim == 2 and "columns" in obj.attrs:
        names = [_attr_text(c) for c in obj.attrs["columns"]]
        if len(names) != obj.shape[1]:
            raise InputError(
                f"{src}: the 'columns' attribute names {len(names)} columns but the dataset has "
                f"{obj.shape[1]}"
            )
        header = names

        def get(i: int) -> np.ndarray:
            return np.asarray(obj[:, i])
    else:
        raise InputError(
            f"{src}: a {obj.ndim}-D dataset without column names; store a compound dataset, a "
            "group of 1-D datasets, or add a 'columns' attribute"
        )
    lengths = None
    if isinstance(obj, h5py.Group):
        lengths = {k: obj[k].shape[0] for k in names}
        if len(set(lengths.values())) > 1:
            raise InputError(
                f"{src}: the column datasets have different lengths "
                f"({', '.join(f'{k}={n}' for k, n in lengths.items())})"
            )
    plan = plan_columns(header, src, columns=opts.columns, channels=opts.channels)
    arrays: dict[int, np.ndarray] = {}
    for i in plan.indices():
        a = get(i)
        if a.dtype.kind not in "fiu":
            raise InputError(f"{src}, column {header[i]!r}: type {a.dtype} is not numeric")
        arrays[i] = a
    time, chans = _raw_from_arrays(plan, arrays)
    return assemble_logs(src, time, chans, opts, notes=plan.notes)


def _with_unit(name: str, unit: str | None) -> str:
    """``gyro_x`` + attribute ``deg/s`` -> ``gyro_x [deg/s]`` (recognised like EuRoC headers)."""
    if unit is None or "[" in name:
        return name
    return f"{name} [{unit}]"
