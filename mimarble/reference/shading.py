"""The rendering model's shading of a hit record: ambient, and each light's diffuse and specular where it is visible.

    L = ka(p)⊙A + Σ_l V(p,l)·I_l⊙(kd(p)·max(0, n·l̂) + ks(p)·max(0, n·ĥ)^shininess)

with V the paper's ``shadowHit`` from p + ε·n (on a smooth mesh, n its shading normal,
from p + ε·n_g, its geometric normal), ε = EPS_REL·(1 + max_k |p_k|)
(:mod:`mimarble.contract`); an area light is n×n point lights at its fixed sample
pattern (:func:`.preparation.area_sample_points`).
"""

from __future__ import annotations

import numpy as np

from mimarble.contract import EPS_REL

from .intersection import HitRecord, fill_channels, occluded
from .preparation import SLOTS, AreaSamples, PreparedScene, area_sample_points
from .shapes import normalize_rows


# ---------------------------------------------------------------------------
# Shading

def shade(prep: PreparedScene, rec: HitRecord, d: np.ndarray | None = None) -> np.ndarray:
    """Radiance of every ray of the batch (N, 3): background on a miss (the scene's
    environment along the ray's unit direction ``d`` (N, 3), when it has one), else the
    formula.

    Computes visibility first, so that channels are evaluated only where used:
    ka where A ≠ 0, kd and ks where at least one light is visible.
    """
    out = np.broadcast_to(prep.background, (rec.count, 3)).copy()
    if prep.environment is not None:
        if d is None:
            raise ValueError("shade: a scene with an environment needs the rays' directions")
        missed = np.ones(rec.count, dtype=bool)
        missed[rec.index] = False
        out[missed] = prep.environment.radiance(np.asarray(d, dtype=np.float64)[missed])
    k = rec.index.size
    if k == 0:
        return out
    p, n, v = rec.p, rec.n, rec.v
    eps = EPS_REL * (1.0 + np.max(np.abs(p), axis=1))
    p_shadow = p + eps[:, None] * (n if rec.ng is None else rec.ng)   # a smooth mesh: off ng

    lights = []                                 # (l_index, visible mask, n·l, n·h)
    areas = []                                  # (Σ I·n·l, Σ I·(n·h)^s) over visible samples
    any_visible = np.zeros(k, dtype=bool)
    shin = prep.shininess[rec.material]
    for li in range(len(prep.light_positions)):
        pattern = prep.light_areas[li] if prep.light_areas else None
        if pattern is not None:
            sums = _area_light(prep, pattern, p, n, v, p_shadow, shin)
            if sums is not None:
                areas.append(sums[1:])
                any_visible |= sums[0]
            continue
        lp = prep.light_positions[li]
        l_hat = normalize_rows(lp - p)
        ndotl = np.einsum("ij,ij->i", n, l_hat)
        front = np.nonzero(ndotl > 0.0)[0]
        visible = np.zeros(k, dtype=bool)
        if front.size:
            seg = lp - p_shadow[front]
            dist = np.linalg.norm(seg, axis=1)
            blocked = occluded(prep, p_shadow[front], seg / dist[:, None], dist)
            visible[front[~blocked]] = True
        if not visible.any():
            continue
        h_hat = normalize_rows(l_hat + v)
        ndoth = np.einsum("ij,ij->i", n, h_hat)
        lights.append((li, visible, ndotl, ndoth))
        any_visible |= visible

    needed = {}
    if np.any(prep.ambient != 0.0):
        needed["ambient"] = np.ones(k, dtype=bool)
    if lights or areas:
        needed["diffuse"] = any_visible
        needed["specular"] = any_visible
    fill_channels(prep, rec, needed)
    ka, kd, ks = (rec.colors.get(s) for s in SLOTS)

    L = np.zeros((k, 3))
    if ka is not None:
        L += ka * prep.ambient
    if kd is not None or ks is not None:
        for diffuse_sum, specular_sum in areas:
            if kd is not None:
                L += kd * diffuse_sum
            if ks is not None:
                L += ks * specular_sum
        for li, visible, ndotl, ndoth in lights:
            term = np.zeros((k, 3))
            if kd is not None:
                term += kd * np.maximum(0.0, ndotl)[:, None]
            if ks is not None:
                term += ks * (np.maximum(0.0, ndoth) ** shin)[:, None]
            L += np.where(visible[:, None], prep.light_colors[li] * term, 0.0)
    out[rec.index] = L
    return out


def _area_light(prep: PreparedScene, pattern: AreaSamples, p, n, v, p_shadow, shin):
    """An area light's samples at hit points p, each a point light of colour I/N:
    (visible to some sample (k,), Σ_s V_s·I_s·max(0, n·l̂_s) (k, 3),
    Σ_s V_s·I_s·max(0, n·ĥ_s)^shininess (k, 3)), or None when no sample is visible."""
    k = len(p)
    seen = np.zeros(k, dtype=bool)
    diffuse_sum = np.zeros(k)
    specular_sum = np.zeros(k)
    for lp in area_sample_points(pattern, p):        # (k, 3) each
        l_hat = normalize_rows(lp - p)
        ndotl = np.einsum("ij,ij->i", n, l_hat)
        front = np.nonzero(ndotl > 0.0)[0]
        if front.size == 0:
            continue
        seg = lp[front] - p_shadow[front]
        dist = np.linalg.norm(seg, axis=1)
        blocked = occluded(prep, p_shadow[front], seg / dist[:, None], dist)
        lit = front[~blocked]
        if lit.size == 0:
            continue
        seen[lit] = True
        diffuse_sum[lit] += ndotl[lit]
        ndoth = np.einsum("ij,ij->i", n[lit], normalize_rows(l_hat[lit] + v[lit]))
        specular_sum[lit] += np.maximum(0.0, ndoth) ** shin[lit]
    if not seen.any():
        return None
    return seen, diffuse_sum[:, None] * pattern.color, specular_sum[:, None] * pattern.color
