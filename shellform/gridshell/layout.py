"""Where the hemisphere's rod nodes sit along the rods, and how they are numbered.

Every rod keeps the distance ``h`` between joints of the Chebyshev net; each
segment between consecutive joints (or a joint and a rod end) is cut into
``round(length / dl)`` equal edges, so every joint is a rod node. A joint is
either two coincident nodes, one per rod (tied later by a penalty spring), or
one node shared by both rods.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.chebyshev import ChebyshevHemisphere


@dataclass
class NodeLayout:
    """The nodes of all rods of a net, numbered.

    Attributes
    ----------
    stations : list of ndarray
        Arc-length coordinate of every node along its rod (the planar position).
    rod_nodes : list of ndarray
        Global node numbers along every rod, in the order of ``net.rods``.
    sphere_nodes, plane_nodes : ndarray (n_nodes, 3)
        Node positions on the net and in the flat footprint.
    joint_keys : list of (int, int)
        ``(u_index, v_index)`` of every joint.
    joint_nodes : ndarray (k, 2)
        For every joint, the node on its u rod and on its v rod (equal for shared joints).
    """

    stations: list
    rod_nodes: list
    sphere_nodes: np.ndarray
    plane_nodes: np.ndarray
    joint_keys: list
    joint_nodes: np.ndarray

    @property
    def end_nodes(self) -> np.ndarray:
        """First and last node of every rod ``(2n, 2)``."""
        return np.array([[idx[0], idx[-1]] for idx in self.rod_nodes], dtype=np.int64)


def rod_stations(rod, h: float, kmax: int, dl: float) -> tuple[np.ndarray, np.ndarray]:
    """Arc-length stations of a rod's nodes and the indices of its joint stations.

    Joints sit at ``l h`` for ``l`` in ``-kmax..kmax`` when inside the rod; each
    segment between consecutive stations (joints and ends) gets
    ``max(1, round(length / dl))`` equal edges.
    """
    joints = [l * h for l in range(-kmax, kmax + 1) if rod.s_start + 1e-9 * h < l * h < rod.s_end - 1e-9 * h]
    knots = np.array([rod.s_start, *joints, rod.s_end])
    pieces, joint_at = [], []
    count = 0
    for a, b in zip(knots[:-1], knots[1:]):
        m = max(1, int(round((b - a) / dl)))
        pieces.append(np.linspace(a, b, m + 1)[:-1])
        count += m
        joint_at.append(count)
    pieces.append(knots[-1:])
    s = np.concatenate(pieces)
    return s, np.array(joint_at[:-1], dtype=np.int64)


def _joint_stations(net: ChebyshevHemisphere, stations: list, joint_idx: list) -> tuple[list, list]:
    """Every joint's key and ``(u rod, station on it, v rod, station on it)``."""
    h = net.spacing
    rod_of = {(r.family, r.index): k for k, r in enumerate(net.rods)}
    joint_keys, joint_station = [], []
    for jt in net.joints:
        ku, kv = rod_of[("u", jt.u_index)], rod_of[("v", jt.v_index)]
        su = stations[ku][joint_idx[ku]]
        sv = stations[kv][joint_idx[kv]]
        iu = joint_idx[ku][int(np.argmin(np.abs(su - jt.v_index * h)))]
        iv = joint_idx[kv][int(np.argmin(np.abs(sv - jt.u_index * h)))]
        joint_keys.append((jt.u_index, jt.v_index))
        joint_station.append((ku, iu, kv, iv))
    return joint_keys, joint_station


def _number_nodes(stations: list, joint_station: list, shared: bool) -> tuple[list, int]:
    """Global node numbers of every rod's stations, and the node count.

    Every rod numbers its own nodes; with ``shared`` joints the v rod's joint
    node is dropped and the u rod's node used instead.
    """
    offsets = np.concatenate([[0], np.cumsum([len(s) for s in stations])])
    local_to_global = [offsets[k] + np.arange(len(s)) for k, s in enumerate(stations)]
    if not shared:
        return local_to_global, int(offsets[-1])
    drop = np.zeros(offsets[-1], dtype=bool)
    for ku, iu, kv, iv in joint_station:
        drop[local_to_global[kv][iv]] = True
    new = np.cumsum(~drop) - 1
    for k in range(len(stations)):
        local_to_global[k] = new[offsets[k] + np.arange(len(stations[k]))]
    for ku, iu, kv, iv in joint_station:
        local_to_global[kv][iv] = local_to_global[ku][iu]
    return local_to_global, int((~drop).sum())


def lay_out_nodes(net: ChebyshevHemisphere, voronoi_length: float, shared: bool) -> NodeLayout:
    """The nodes of every rod of ``net`` (u rods first, then v rods), about ``voronoi_length`` apart."""
    h = net.spacing
    kmax = (net.n - 1) // 2
    stations, joint_idx = [], []
    for rod in net.rods:
        s, jidx = rod_stations(rod, h, kmax, voronoi_length)
        stations.append(s)
        joint_idx.append(jidx)
    joint_keys, joint_station = _joint_stations(net, stations, joint_idx)
    local_to_global, n_nodes = _number_nodes(stations, joint_station, shared)
    sphere_nodes = np.zeros((n_nodes, 3))
    plane_nodes = np.zeros((n_nodes, 3))
    for rod, s, idx in zip(net.rods, stations, local_to_global):
        sphere_nodes[idx] = rod.position(s)
        plane_nodes[idx] = rod.planar(s, h)
    joint_nodes = np.array(
        [(local_to_global[ku][iu], local_to_global[kv][iv]) for ku, iu, kv, iv in joint_station], dtype=np.int64
    )
    return NodeLayout(stations=stations, rod_nodes=local_to_global, sphere_nodes=sphere_nodes,
                      plane_nodes=plane_nodes, joint_keys=joint_keys, joint_nodes=joint_nodes)
