"""Arrow columns for Rerun's ``send_record_batch``: a recording's flush is one record batch.

The batch has an index column per timeline (:data:`INDEX_FIELDS`: ``step``, a sequence, and
``time``, a duration) and a column per (entity, component), each field described by the
``rerun:*`` metadata that ``rerun.chunk.Chunk.from_record_batch`` reads (kind, entity path,
archetype, component, component type, taken from Rerun's own descriptors:
:func:`component_field`). Component columns are lists, one batch per row (:func:`rows`), of
the component's Arrow type, also taken from Rerun's own conversions (:func:`arrow_type`);
scalar columns may be plain float64 with nulls where a series has no sample (Rerun wraps each
value as a one-element list). :func:`episode_returns` computes the return column.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Optional

import numpy as np
import pyarrow as pa
import rerun as rr

_TYPES: dict = {}

#: The index fields of the ``step`` (int64 sequence) and ``time`` (duration [ns]) timelines.
INDEX_FIELDS = (pa.field("step", pa.int64(), metadata={"rerun:kind": "index", "rerun:index_name": "step"}),
                pa.field("time", pa.duration("ns"), metadata={"rerun:kind": "index", "rerun:index_name": "time"}))


def arrow_type(kind: str) -> pa.DataType:
    """The Arrow type of Rerun's component ``kind``: position, vector, translation, mat3x3,
    strip or color."""
    if not _TYPES:
        c = rr.components
        _TYPES.update(
            position=c.Position3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            vector=c.Vector3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            translation=c.Translation3DBatch([[0.0, 0.0, 0.0]]).as_arrow_array().type,
            mat3x3=c.TransformMat3x3Batch(np.eye(3)).as_arrow_array().type,
            strip=c.LineStrip3DBatch([[[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]]).as_arrow_array().type,
            color=c.ColorBatch([0]).as_arrow_array().type)
    return _TYPES[kind]


@lru_cache(maxsize=None)
def _field(path: str, component: str, archetype: str, component_type: str, type_: pa.DataType) -> pa.Field:
    return pa.field(f"{path}:{component}", type_, metadata={
        "rerun:kind": "data", "rerun:entity_path": path, "rerun:archetype": archetype,
        "rerun:component": component, "rerun:component_type": component_type})


def component_field(path: str, descriptor, type_: pa.DataType) -> pa.Field:
    """The record-batch field of ``descriptor``'s component of entity ``path`` (cached)."""
    return _field(path, descriptor.component, descriptor.archetype or "", descriptor.component_type or "", type_)


def vec3(a: np.ndarray, kind: str) -> pa.Array:
    """(m, 3) -> FixedSizeList<float32, 3> array of Rerun's ``kind`` type."""
    flat = pa.array(np.ascontiguousarray(a, dtype=np.float32).reshape(-1))
    return pa.FixedSizeListArray.from_arrays(flat, type=arrow_type(kind))


def mat3x3(a: np.ndarray) -> pa.Array:
    """(m, 9) column-major float32 matrices -> Rerun's TransformMat3x3 array."""
    return pa.FixedSizeListArray.from_arrays(pa.array(a.reshape(-1)), type=arrow_type("mat3x3"))


def strips(points: np.ndarray, offsets: np.ndarray) -> pa.Array:
    """LineStrip3D array from points (P, 3) and strip offsets (S + 1,)."""
    return pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), vec3(points, "position"),
                                    type=arrow_type("strip"))


def rows(values: pa.Array, offsets: np.ndarray, missing: Optional[np.ndarray] = None) -> pa.Array:
    """Group ``values`` into one list per sample (row k holds values[offsets[k]:offsets[k+1]]);
    ``missing`` rows are null (no data; an empty list would clear the entity)."""
    mask = None if missing is None else pa.array(missing)
    return pa.ListArray.from_arrays(pa.array(offsets, type=pa.int32()), values, type=pa.list_(values.type),
                                    mask=mask)


def record_batch(steps: np.ndarray, times: np.ndarray, columns) -> pa.RecordBatch:
    """One record batch: the ``step`` and ``time`` [s] indexes of its rows and ``columns``, a
    sequence of (entity path, component descriptor, values)."""
    fields = list(INDEX_FIELDS)
    arrays = [pa.array(steps.astype(np.int64)), pa.array(np.rint(times * 1e9).astype(np.int64), type=pa.duration("ns"))]
    for path, descriptor, values in columns:
        fields.append(component_field(path, descriptor, values.type))
        arrays.append(values)
    return pa.RecordBatch.from_arrays(arrays, schema=pa.schema(fields))


def episode_returns(rewards: np.ndarray, episode: np.ndarray, stepped: np.ndarray, carry: tuple) -> tuple:
    """The running sum of the rewards of stepped samples within each episode, carried across
    record batches: ``carry`` is (episode, return) at the end of the previous batch; returns the
    column and the new carry."""
    vals = np.where(stepped, rewards, 0.0)
    if episode[0] == carry[0]:
        vals[0] += carry[1]
    idx = np.arange(len(vals))
    start = np.maximum.accumulate(np.where(np.r_[True, episode[1:] != episode[:-1]], idx, 0))
    cs = np.cumsum(vals)
    out = cs - (cs[start] - vals[start])
    return out, (episode[-1], float(out[-1]))
