"""Moving loads on an Exudyn body: the path data it carries and the user functions that move the load.

A body reduced with moving loads (:mod:`flexmor.moving`, ``reduce --moving-load SET:DIR``) keeps each path in
``body.info["moving_loads"]``. Its Exudyn data (:func:`flexmor.io.exudyn.exudyn_data`, the ``.exudyn.npz`` file
of :func:`~flexmor.io.exudyn.write_exudyn`, and ``res["moving_loads"]`` of
:func:`~flexmor.io.exudyn.add_to_exudyn` / :func:`~flexmor.io.exudyn.add_npz_to_exudyn`) carries the paths as
flat arrays (:data:`MOVING_KEYS`; the nodes of path ``k`` are entries ``offsets[k]:offsets[k+1]``):

========================  ============  ================================================================
``movingLoadSpecs``       (P,) str      ``SET:DIR@AXIS`` of each path
``movingLoadDirections``  (P,) str      ``x``, ``y`` or ``z``: the force's axis in the body's frame
``movingLoadOffsets``     (P + 1,) int  where each path's nodes start in the arrays below
``movingLoadNodes``       (ΣN,) int     FE node ids, in path order
``movingLoadMeshNodes``   (ΣN,) int     their Exudyn mesh nodes
``movingLoadS``           (ΣN,)         arc length of each node from its path's first node (m)
``movingLoadXYZ``         (ΣN, 3)       reference positions of the nodes in the body's frame
``movingLoadBPath``       (r, ΣN)       the reduced input of a unit force at each node: the row of the
                                        mode basis ``modeBasis`` at the node in the load's direction
                                        (``V^T B_path`` of ``body.info``)
========================  ============  ================================================================

A force ``F`` at arc length ``s`` is shared by the two path nodes around it, linearly in ``s`` (the
interpolation of :func:`flexmor.moving.hat_weights`; nothing off the path): its reduced input is
``B_r(s) F = B_path w(s) F`` and the deflection under it ``w(s)^T B_path^T q``.

:func:`moving_load_force` is the ``forceUserFunction`` of the ``ObjectFFRFreducedOrder`` that applies
``B_r(s(t)) F(t)`` to the body's **modal coordinates** (the object's last ``r`` coordinates; its frame node's
coordinates come first). For a body whose frame is held (fixed to the ground: a bridge, a rail, the clamped body
of a supported model) that is the whole load. A floating frame is pushed and turned by the load as well: add its
resultant ``F`` and its moment ``x(s) x F`` about the frame's origin at the frame node
(:func:`moving_load_frame_loads`; ``x(s)`` the reference position under the load, the deflection's share of the
lever arm left out). :func:`under_load` and :func:`under_load_sensor` give the deflection under the load.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError, OptionError

__all__ = ["MOVING_KEYS", "MovingPath", "moving_load_data", "path_data", "moving_load_force", "moving_load_frame_loads",
           "under_load", "under_load_sensor"]

#: Keys of the moving-load data in an Exudyn body's data (module docstring).
MOVING_KEYS = ("movingLoadSpecs", "movingLoadDirections", "movingLoadOffsets", "movingLoadNodes",
               "movingLoadMeshNodes", "movingLoadS", "movingLoadXYZ", "movingLoadBPath")


def moving_load_data(body, node_ids, Psi, xyz) -> dict:
    """The moving-load keys (:data:`MOVING_KEYS`) of a body whose Exudyn mesh has the nodes ``node_ids``, the
    mode basis ``Psi`` (3 rows per mesh node) and the reference positions ``xyz`` (flat, 3 per mesh node);
    ``{}`` for a body without moving loads."""
    loads = body.info.get("moving_loads") if isinstance(body.info, dict) else None
    if not loads:
        return {}
    index = {int(k): i for i, k in enumerate(np.asarray(node_ids))}
    nodes = [np.asarray(ml["nodes"], dtype=np.int64) for ml in loads]
    missing = [int(k) for n in nodes for k in n if int(k) not in index]
    if missing:
        raise ModelError(f"the moving load's path nodes {missing[:5]} are not nodes of the model given: export the "
                         "body with the model it was reduced from", params=("model",))
    mesh = np.array([index[int(k)] for n in nodes for k in n], dtype=np.int64)
    axis = np.concatenate([np.full(n.size, "xyz".index(str(ml["direction"]))) for n, ml in zip(nodes, loads)])
    return {"movingLoadSpecs": np.array([str(ml["spec"]) for ml in loads], dtype=str),
            "movingLoadDirections": np.array([str(ml["direction"]) for ml in loads], dtype=str),
            "movingLoadOffsets": np.cumsum([0] + [n.size for n in nodes]).astype(np.int64),
            "movingLoadNodes": np.concatenate(nodes), "movingLoadMeshNodes": mesh,
            "movingLoadS": np.concatenate([np.asarray(ml["s"], float) for ml in loads]),
            "movingLoadXYZ": np.asarray(xyz, float).reshape(-1, 3)[mesh],
            "movingLoadBPath": np.asarray(Psi, float)[3 * mesh + axis].T.copy()}


@dataclass(frozen=True)
class MovingPath:
    """One path of an Exudyn body's moving-load data (:func:`path_data`).

    Attributes
    ----------
    spec, direction : str
    axis : int
        0, 1, 2 for ``x``, ``y``, ``z``.
    nodes, mesh_nodes : ndarray of int, shape (N,)
    s : ndarray, shape (N,)
        Arc lengths (m), increasing.
    xyz : ndarray, shape (N, 3)
    B : ndarray, shape (r, N)
        ``V^T B_path``.
    """

    spec: str
    direction: str
    axis: int
    nodes: np.ndarray
    mesh_nodes: np.ndarray
    s: np.ndarray
    xyz: np.ndarray
    B: np.ndarray

    @property
    def length(self) -> float:
        """Length of the path (m)."""
        return float(self.s[-1])

    def segment(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(j, t, on)`` of positions ``s``: the segment from node ``j`` to ``j + 1`` each lies on, its
        fraction ``t`` of the way and whether it is on the path at all (arrays shaped as ``s``)."""
        s = np.asarray(s, float)
        j = np.clip(np.searchsorted(self.s, s, side="right") - 1, 0, self.s.size - 2)
        t = (s - self.s[j]) / (self.s[j + 1] - self.s[j])
        return j, t, (s >= self.s[0]) & (s <= self.s[-1])

    def input(self, s: float) -> np.ndarray:
        """``B_r(s) = B_path w(s)`` (r,): the reduced input of a unit force at ``s`` (zero off the path)."""
        j, t, on = self.segment(s)
        return (self.B[:, j] * (1.0 - t) + self.B[:, j + 1] * t) if on else np.zeros(self.B.shape[0])

    def position(self, s: float) -> np.ndarray:
        """The reference position (3,) of the point at ``s`` in the body's frame."""
        j, t, _ = self.segment(s)
        return self.xyz[j] * (1.0 - t) + self.xyz[j + 1] * t


def _arrays(source):
    """The mapping of :data:`MOVING_KEYS` in ``source`` (exudyn data, an ``.exudyn.npz`` file or the result of
    ``add_to_exudyn``)."""
    if "moving_loads" in source:  # the result of add_to_exudyn / add_npz_to_exudyn
        source = source["moving_loads"]
    if MOVING_KEYS[0] not in source:
        raise OptionError("the Exudyn body carries no moving load: reduce it with a moving load (reduce --moving-load "
                          "SET:DIR, System(moving_loads=[...])) and export it again", params=("moving_load",))
    return source


def path_data(source, k: int = 0) -> MovingPath:
    """The ``k``-th path of an Exudyn body's moving-load data: ``source`` the dict of
    :func:`~flexmor.io.exudyn.exudyn_data`, an opened ``.exudyn.npz`` (``np.load(path, allow_pickle=False)``) or
    the result of :func:`~flexmor.io.exudyn.add_to_exudyn`."""
    a = _arrays(source)
    specs = [str(v) for v in np.atleast_1d(a["movingLoadSpecs"])]
    if not -len(specs) <= k < len(specs):
        raise OptionError(f"moving load {k} asked for; the body has {len(specs)} ({', '.join(specs)})",
                          params=("k",))
    k = k % len(specs)
    off = np.asarray(a["movingLoadOffsets"])
    at = slice(int(off[k]), int(off[k + 1]))
    d = str(np.atleast_1d(a["movingLoadDirections"])[k])
    return MovingPath(specs[k], d, "xyz".index(d), np.asarray(a["movingLoadNodes"])[at],
                      np.asarray(a["movingLoadMeshNodes"])[at], np.asarray(a["movingLoadS"], float)[at],
                      np.asarray(a["movingLoadXYZ"], float).reshape(-1, 3)[at],
                      np.asarray(a["movingLoadBPath"], float)[:, at])


def _motion(speed, position, start, force):
    """``(s(t), F(t))`` of a load moving at ``speed`` from ``start`` or along ``position(t)``, of ``force``."""
    if (speed is None) == (position is None):
        raise OptionError("give the load's motion as speed (m/s, from start) or as position(t) (m), one of them",
                          params=("speed", "position"))
    if position is None:
        v, s0 = float(speed), float(start)

        def position(t):
            return s0 + v * t

    if not callable(force):
        F = float(force)

        def force(t):
            return F

    return position, force


def moving_load_force(source, *, speed: float | None = None, position=None, start: float = 0.0, force=1.0,
                      k: int = 0, add=None):
    """The ``forceUserFunction`` of an ``ObjectFFRFreducedOrder`` that moves a force over the body's ``k``-th path.

    It returns ``B_r(s(t)) F(t)`` on the object's modal coordinates (its last ``r``) and zero on its frame's
    (module docstring: for a frame held; :func:`moving_load_frame_loads` adds the frame's share). Set it with::

        res = add_to_exudyn(mbs, body, model)             # or add_npz_to_exudyn(mbs, "body.exudyn.npz")
        mbs.SetObjectParameter(res["oFFRFreducedOrder"], "forceUserFunction",
                               moving_load_force(res, speed=10.0, force=-1000.0))

    Parameters
    ----------
    source
        The body's moving-load data (:func:`path_data`): the result of ``add_to_exudyn``, the dict of
        ``exudyn_data`` or an opened ``.exudyn.npz``.
    speed : float, optional
        The load moves at ``speed`` (m/s) from arc length ``start`` (m) at t = 0 ...
    position : callable, optional
        ... or stands at ``position(t)`` (m); one of the two. Off the path (``s < 0`` or beyond its length) the
        load acts on nothing.
    force : float or callable
        The force (N, or ``force(t)``) along the path's direction in the body's frame (``+z`` for ``SET:z``).
    k : int
        Which path.
    add : callable, optional
        Another force user function whose forces are added (the body has one ``forceUserFunction``: e.g.
        :func:`flexmor.io.exudyn.spin_stiffening_force`, which ``add_to_exudyn`` sets on a spinning body).
    """
    path = path_data(source, k)
    s_of, F_of = _motion(speed, position, start, force)
    r = path.B.shape[0]

    def load(mbs, t, itemNumber, q, q_t):
        out = np.zeros(len(q)) if add is None else np.array(add(mbs, t, itemNumber, q, q_t), dtype=float)
        out[len(q) - r:] += path.input(s_of(t)) * F_of(t)
        return out.tolist()

    return load


def moving_load_frame_loads(mbs, res: dict, *, speed: float | None = None, position=None, start: float = 0.0,
                            force=1.0, k: int = 0) -> tuple[int, int]:
    """The floating frame's share of the moving load of :func:`moving_load_force` (same arguments): its
    resultant ``F`` along the path's direction and its moment ``x(s) x F`` about the frame's origin, body-fixed
    loads at the frame node of ``res`` (the result of ``add_to_exudyn``), ``x(s)`` the reference position under
    the load (the lever arm of the deflection, small, left out). Not for a frame held to the ground (the support
    takes them). Returns the load numbers (force, torque)."""
    import exudyn.itemInterface as eii

    path = path_data(res, k)
    s_of, F_of = _motion(speed, position, start, force)

    def resultant(t) -> np.ndarray:
        f = np.zeros(3)
        s = s_of(t)
        f[path.axis] = F_of(t) if path.s[0] <= s <= path.s[-1] else 0.0
        return f

    def push(mbs_, t, load):
        return resultant(t).tolist()

    def turn(mbs_, t, load):
        return np.cross(path.position(s_of(t)), resultant(t)).tolist()

    marker = mbs.AddMarker(eii.MarkerNodeRigid(nodeNumber=res["nRigidBody"]))
    return (mbs.AddLoad(eii.LoadForceVector(markerNumber=marker, bodyFixed=True, loadVectorUserFunction=push)),
            mbs.AddLoad(eii.LoadTorqueVector(markerNumber=marker, bodyFixed=True, loadVectorUserFunction=turn)))


def under_load(source, s, q, k: int = 0):
    """The deflection under the load at ``s`` along the path's direction, ``w(s)^T B_path^T q``, from the modal
    coordinates ``q`` (r,) or (T, r) at ``s`` (scalar or (T,)); wider ``q`` (the object's coordinates, frame's
    first) give their last ``r``. ``source`` as in :func:`path_data`. Zero off the path."""
    path = path_data(source, k)
    r = path.B.shape[0]
    q = np.asarray(q, float)
    if q.shape[-1] < r:
        raise OptionError(f"q has {q.shape[-1]} coordinates; the body has {r} modal coordinates", params=("q",))
    return _deflection(path, *path.segment(s), q[..., q.shape[-1] - r:])


def _deflection(path: MovingPath, j, t, on, y):
    """``w(s)^T B^T y`` from the segments ``(j, t, on)`` of ``s`` and modal coordinates ``y`` (..., r)."""
    Bj = path.B[:, j].T * (1.0 - np.asarray(t))[..., None] + path.B[:, j + 1].T * np.asarray(t)[..., None]
    out = np.where(on, np.sum(Bj * y, axis=-1), 0.0)
    return float(out) if np.ndim(out) == 0 else out


def under_load_sensor(mbs, res: dict, *, speed: float | None = None, position=None, start: float = 0.0, k: int = 0,
                      store: bool = True, name: str = "") -> int:
    """A ``SensorUserFunction`` of the deflection under the moving load (:func:`under_load`) of the body of
    ``res`` (the result of ``add_to_exudyn``), the load moving as given to :func:`moving_load_force`; stored
    internally with ``store`` (``mbs.GetSensorStoredData(sensor)``: time, deflection). Returns the sensor number."""
    import exudyn as exu
    import exudyn.itemInterface as eii

    path = path_data(res, k)
    s_of, _ = _motion(speed, position, start, 1.0)
    node = res["nGenericODE2"]

    def sense(mbs_, t, sensorNumbers, factors, configuration):
        q = np.asarray(mbs_.GetNodeOutput(node, exu.OutputVariableType.Coordinates, configuration=configuration))
        return [_deflection(path, *path.segment(s_of(t)), q)]

    return mbs.AddSensor(eii.SensorUserFunction(name=name, sensorUserFunction=sense, storeInternal=store))
