"""Random P/T nets for the property tests (hypothesis strategies)."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from shared.tasknet.ptnet import PTNet, net_from_matrices


@st.composite
def small_nets(draw, max_places: int = 5, max_transitions: int = 5, capacities: bool = False) -> PTNet:
    n_p = draw(st.integers(1, max_places))
    n_t = draw(st.integers(1, max_transitions))
    matrix = st.lists(st.lists(st.integers(0, 2), min_size=n_t, max_size=n_t), min_size=n_p, max_size=n_p)
    pre = np.array(draw(matrix)).reshape(n_p, n_t)
    post = np.array(draw(matrix)).reshape(n_p, n_t)
    m0 = np.array(draw(st.lists(st.integers(0, 2), min_size=n_p, max_size=n_p)))
    caps = None
    if capacities:
        caps = [draw(st.one_of(st.none(), st.integers(max(1, int(m0[i])), 4))) for i in range(n_p)]
    return net_from_matrices(pre, post, m0, capacity=caps)
