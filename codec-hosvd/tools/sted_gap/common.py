"""What the three experiments share: paths, loading, the mesh graph, the entropy proxy and
hosvd's unquantized operator (no motion removal)."""
import os, sys
import numpy as np, scipy.sparse as sp

SHARED = os.environ.get('ANIMCODEC_SHARED',
                        os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..', '..', 'shared'))
sys.path.insert(0, os.path.join(SHARED, 'peers'))
from sted_np import sted_parts  # noqa: E402  (the reference STED, re-exported)
from anim import load_pc2, load_obj_faces  # noqa: E402


def load(name):
    """Frames (F, V, 3) as float64 and faces (K, 3) of ../shared/data/NAME."""
    A = load_pc2(f'{SHARED}/data/{name}/{name}.pc2')
    A = np.asarray(A[0] if isinstance(A, tuple) else A, float)
    faces = np.asarray(load_obj_faces(f'{SHARED}/data/{name}/{name}.obj'))
    return A, faces


def mesh(faces, V):
    """Unique edges E, adjacency Adj, degrees, and the uniform Laplacian I − D⁻¹·Adj."""
    E = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    Adj = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(V, V)).tocsr()
    deg = np.asarray(Adj.sum(1)).ravel()
    Lap = sp.identity(V) - sp.diags(1 / np.maximum(deg, 1)) @ Adj
    return E, Adj, deg, Lap


def H(q):
    """Zero-order entropy (bits) of the integers q."""
    _, c = np.unique(q, return_counts=True)
    p = c / c.sum()
    return -(c * np.log2(p)).sum()


def hosvd(T, v, f):
    """Truncated HO-SVD of T (V × 3 × F): U1 (V × v), U3 (F × f), core (v × 3 × f)."""
    V, F = T.shape[0], T.shape[2]
    U1 = np.linalg.svd(T.reshape(V, -1), full_matrices=False)[0][:, :v]
    U3 = np.linalg.svd(T.transpose(2, 0, 1).reshape(F, -1), full_matrices=False)[0][:, :f]
    C = np.einsum('vcf,vi,fl->icl', T, U1, U3)
    return U1, U3, C
