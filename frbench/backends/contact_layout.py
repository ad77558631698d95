"""Where a robot's contact groups, feet and knee groups lie among its simulated links, for summarising the
per-link contact forces of N simulations with a few array operations per control step.

`ContactLayout` is built once per (link names, groups) and cached; `frbench.backends.base.summarize_contacts`
reads it. Every reduction keeps the order of the per-group loop it replaces (a group's forces are added
link after link), so the summaries are bit-identical to it. The forces may be numpy arrays or torch tensors on a
device (`frbench.arrays`): the layout's index arrays then go to that device once (`frbench.arrays.resident`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from frbench.arrays import is_host, namespace, resident


def as_slice(index: np.ndarray) -> "slice | np.ndarray":
    """``index`` (k,) ints as a slice when it is a run of consecutive ascending values (a view, no copy), else
    itself."""
    index = np.asarray(index)
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0]) + index.size)
    return index


def vector_norm(vectors):
    """Euclidean norm over the last axis, (…, k) → (…): the same operations as ``np.linalg.norm(v, axis=-1)``
    of real input (squares, then ``add.reduce``, then ``sqrt``), without its argument checks; numpy or torch."""
    xp = namespace(vectors)
    return xp.sqrt(xp.sum(vectors * vectors, axis=-1))


def on_device(index, ref):
    """An index (a slice, or an int array) for arrays like ``ref``: itself for numpy and for a slice, else the
    index array on ``ref``'s device (converted once)."""
    if isinstance(index, slice) or is_host(ref):
        return index
    return resident(index, ref, namespace(ref).int64)


class ContactLayout:
    """Index arrays of one robot's link groups among ``link_names`` (n_links names).

    Attributes:
        membership: (n_links, n_groups) bool, link l belongs to contact group g.
        feet: (n_feet,) indices of the foot links (a slice when consecutive).
        non_foot: (n_links − n_feet,) indices of the other links (a slice when consecutive).
        knee_columns: (k,) index arrays, column j the j-th link of every knee group, when all knee groups
            have the same number k < 8 of links (None otherwise: `knee_sum` then loops over the groups).
        knee_groups: the knee groups' index arrays.
    """

    def __init__(self, link_names: tuple[str, ...], contact_groups, knee_groups, foot_links: tuple[str, ...]):
        where = {name: i for i, name in enumerate(link_names)}
        self.membership = np.zeros((len(link_names), len(contact_groups)), dtype=bool)
        for g, group in enumerate(contact_groups):
            self.membership[[where[link] for link in group.links], g] = True
        feet = np.array([where[f] for f in foot_links], dtype=int)
        self.feet = as_slice(feet)
        self.non_foot = as_slice(np.setdiff1d(np.arange(len(link_names)), feet))
        self.has_non_foot = len(link_names) > len(feet)
        self.knee_groups = [np.array([where[link] for link in group.links]) for group in knee_groups]
        sizes = {len(idx) for idx in self.knee_groups}
        self.knee_columns = None
        if len(sizes) == 1 and 0 < next(iter(sizes)) < 8:
            table = np.stack(self.knee_groups)
            self.knee_columns = [as_slice(table[:, j]) for j in range(table.shape[1])]

    def group_contact(self, touching):
        """(N, n_groups) bool: any link of the group touches, from ``touching`` (N, n_links) bool (numpy or torch)."""
        if is_host(touching):
            return touching @ self.membership
        xp = namespace(touching)  # torch multiplies no booleans: any link of the group, elementwise (no BLAS call)
        membership = resident(self.membership, touching, xp.bool)
        return xp.any(touching[:, :, None] & membership[None], axis=1)

    def knee_sum(self, link_force):
        """(N, n_knee_groups, 3) [N]: each knee group's forces added link after link, from (N, n_links, 3)."""
        xp = namespace(link_force)
        if self.knee_columns is None:
            return xp.stack([xp.sum(link_force[:, on_device(idx, link_force)], axis=1) for idx in self.knee_groups],
                            axis=1)
        total = 0.0 + link_force[:, on_device(self.knee_columns[0], link_force)]  # ``sum`` starts from its identity, 0
        for column in self.knee_columns[1:]:
            total = total + link_force[:, on_device(column, link_force)]
        return total


@lru_cache(maxsize=64)
def contact_layout(link_names: tuple[str, ...], contact_groups, knee_groups,
                   foot_links: tuple[str, ...]) -> ContactLayout:
    """The cached `ContactLayout` of one robot's links and groups."""
    return ContactLayout(link_names, contact_groups, knee_groups, foot_links)
