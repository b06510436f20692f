#!/usr/bin/env python3
"""Independent synthetic NIGHT scenes (linear HDR -> OpenEXR), a TEST-ONLY set.

A night-scene generator written by a helper WITHOUT reading the project's own scene generator
(hdrcam's procedural scenes), and it imports nothing from hdrcam. Its scenes measure how the networks
generalise to night scenes from a generator they never saw: never add them to training or validation data,
or they stop measuring generalisation across generators.

Units: linear RGB (Rec.709 primaries), arbitrary scale, 1.0 ~ a bright diffuse white surface under street
light (sky ~0.001-0.02, lit windows 0.3-5, lamp cores 20-3000, headlights up to 5000; clipped at 1e5).

    python tools/independent_night_scenes.py --count 24 --seed 7 --out DIR

The reported set is seed 7, 24 scenes (tools/measure_generalisation.sh); development work may use other
seeds. Output is deterministic for a given --seed (scene i depends on the seed and i only, so a smaller
--count gives the first scenes of a larger one) and independent of --jobs. Each scene is written as
DIR/night-gen-NNN.exr (float32 RGB, ZIP, 1024 x 1024), read back to verify, and summarised on one line
(scene type, min / median / p99 / max luminance, fraction of pixels above 1.0); a scene file already in DIR is
refused in one line (exit 1) unless --overwrite. --contact PATH also writes
a PNG contact sheet (256 px thumbnails, x/(1+x), gamma 1/2.2).

Each scene is produced by a tiny deferred renderer written from scratch here:
  * pin-hole camera without rotation (lens shift sets the horizon / vanishing point),
  * axis-aligned boxes (buildings with window grids, cars, poles, furniture),
    a ground plane (road / sidewalk / grass / water), billboard foliage, sky dome,
  * point lights (street lamps, headlights, room lamps) with inverse-square fall-off
    and simple beam lobes -> pools of light on the ground / walls,
  * emissive details: lamp cores with glow (+ optional diffraction spikes), neon strokes,
    light trails, stars, moon with halo,
  * wet-road / water reflections: vertically blurred mirror copies of everything above.
Scene types: avenue, across (facades across a street), skyline (city across water), park, interior (about
1 scene in 6).
Dependencies: numpy, opencv (cv2), OpenEXR (>= 3.3 Python API).
"""
import argparse
import math
import multiprocessing as mp
import os
import sys
import time

import numpy as np
import cv2
import OpenEXR

H = W = 1024
F = np.float32
LUMW = np.array([0.2126, 0.7152, 0.0722], F)


def col(r, g, b):
    return np.array([r, g, b], F)


STREET = {
    'sodium_lp': col(1.00, 0.47, 0.05),
    'sodium_hp': col(1.00, 0.62, 0.27),
    'led_warm': col(1.00, 0.80, 0.58),
    'led_neutral': col(1.00, 0.94, 0.86),
    'led_cool': col(0.80, 0.90, 1.00),
    'mercury': col(0.70, 1.00, 0.86),
    'metal_halide': col(0.92, 1.00, 0.97),
}
INDOOR = {
    'incandescent': col(1.00, 0.64, 0.33),
    'halogen': col(1.00, 0.76, 0.50),
    'warm_led': col(1.00, 0.80, 0.60),
    'neutral_led': col(1.00, 0.93, 0.84),
    'fluorescent': col(0.86, 1.00, 0.94),
    'cool_led': col(0.84, 0.91, 1.00),
}
NEON = {
    'red': col(1.00, 0.07, 0.04), 'pink': col(1.00, 0.16, 0.62), 'magenta': col(0.95, 0.10, 1.00),
    'blue': col(0.10, 0.30, 1.00), 'cyan': col(0.10, 0.90, 1.00), 'green': col(0.20, 1.00, 0.30),
    'orange': col(1.00, 0.42, 0.04), 'yellow': col(1.00, 0.85, 0.15), 'white': col(0.90, 0.95, 1.00),
    'purple': col(0.55, 0.15, 1.00),
}
WINDOW_PAL = np.array([
    [1.00, 0.62, 0.30],  # incandescent
    [1.00, 0.74, 0.46],  # halogen / warm
    [1.00, 0.84, 0.64],  # warm LED
    [0.95, 0.97, 1.00],  # cool LED
    [0.84, 1.00, 0.92],  # fluorescent (green-ish)
    [0.55, 0.70, 1.00],  # TV blue
    [1.00, 0.45, 0.40],  # red curtain
], F)
PAL_HOME = np.array([0.25, 0.28, 0.25, 0.07, 0.04, 0.08, 0.03])
PAL_OFFICE = np.array([0.02, 0.04, 0.12, 0.45, 0.34, 0.02, 0.01])
WORDS = ["BAR", "HOTEL", "OPEN", "CAFE", "PIZZA", "MOTEL", "24H", "CLUB", "DINER", "RAMEN",
         "SUSHI", "LIQUOR", "KARAOKE", "PHARMACY", "TAXI", "NOODLES", "JAZZ", "BEER", "DANCE",
         "CASINO", "LOUNGE", "KEBAB", "PARKING", "CINEMA", "GRILL", "BURGER", "TATTOO", "PUB"]
FONTS = [cv2.FONT_HERSHEY_SIMPLEX, cv2.FONT_HERSHEY_DUPLEX, cv2.FONT_HERSHEY_SCRIPT_SIMPLEX,
         cv2.FONT_HERSHEY_PLAIN, cv2.FONT_HERSHEY_COMPLEX_SMALL, cv2.FONT_HERSHEY_SCRIPT_COMPLEX]
# normals by id: 0 none(sky) 1 +Y(up) 2 +X 3 -X 4 -Z(faces camera) 5 +Z 6 -Y(down) 7 isotropic
NORM = np.array([[0, 0, 0], [0, 1, 0], [1, 0, 0], [-1, 0, 0], [0, 0, -1], [0, 0, 1], [0, -1, 0],
                 [0, 0, 0]], F)
# surface kinds
K_SKY, K_GROUND, K_BUILD, K_FOLIAGE, K_OBJ, K_GLASS, K_FIXT = range(7)


# ----------------------------------------------------------------------------- utils
def U(rng, a, b):
    return float(rng.uniform(a, b))


def LU(rng, a, b):
    return float(math.exp(rng.uniform(math.log(a), math.log(b))))


def chance(rng, p):
    return bool(rng.random() < p)


def pick(rng, seq, p=None):
    return seq[int(rng.choice(len(seq), p=p))]


def fbm(rng, h, w, cell, octaves=4, gain=0.5):
    """Value-noise fBm, roughly zero mean / unit std."""
    h, w = max(int(h), 1), max(int(w), 1)
    out = np.zeros((h, w), F)
    amp, tot, c = 1.0, 0.0, max(float(cell), 1.5)
    for _ in range(octaves):
        gh, gw = int(h / c) + 3, int(w / c) + 3
        g = rng.standard_normal((gh, gw)).astype(F)
        up = cv2.resize(g, (int(gw * c), int(gh * c)), interpolation=cv2.INTER_CUBIC)
        oy = int(rng.integers(0, max(1, up.shape[0] - h)))
        ox = int(rng.integers(0, max(1, up.shape[1] - w)))
        out += amp * up[oy:oy + h, ox:ox + w]
        tot += amp * amp
        amp *= gain
        c = max(c / 2.0, 1.5)
    return out / F(math.sqrt(tot) * 0.8)


def hash01(a, b, salt):
    """Deterministic per-cell random numbers in [0,1)."""
    a = np.asarray(a, np.int64)
    b = np.asarray(b, np.int64)
    x = (a * 73856093) ^ (b * 19349663) ^ (np.asarray(salt, np.int64) * 83492791)
    x = (x & 0xFFFFFFFF).astype(np.uint32)
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7feb352d)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846ca68b)
    x ^= x >> np.uint32(16)
    return (x >> np.uint32(8)).astype(F) * F(1.0 / 16777216.0)


def box_cov(t, p, a, w):
    """Box-filtered coverage of the periodic pulse [a, a+w) (period 1) over footprint p."""
    p = np.maximum(p, 1e-3)

    def Fi(x):
        fl = np.floor(x)
        return fl * w + np.clip(x - fl - a, 0, w)
    return np.clip((Fi(t + p / 2) - Fi(t - p / 2)) / p, 0, 1)


def interval_cov(x, p, a, b):
    p = np.maximum(p, 1e-4)
    return np.clip((np.minimum(b, x + p / 2) - np.maximum(a, x - p / 2)) / p, 0, 1)


def smoothstep(a, b, x):
    t = np.clip((x - a) / (b - a), 0, 1)
    return t * t * (3 - 2 * t)


# ----------------------------------------------------------------------------- camera / scene
class Cam:
    def __init__(self, f, hc, xv, yh):
        self.f, self.hc, self.xv, self.yh = float(f), float(hc), float(xv), float(yh)
        dx = ((np.arange(W) + 0.5 - xv) / f).astype(F)
        dx[np.abs(dx) < 1e-7] = 1e-7
        dy = (-(np.arange(H) + 0.5 - yh) / f).astype(F)
        dy[np.abs(dy) < 1e-7] = 1e-7
        self.dx, self.dy = dx, dy

    def proj(self, X, Y, Z):
        return self.xv + self.f * X / Z, self.yh + self.f * (self.hc - Y) / Z


class Light:
    def __init__(self, pos, colr, I=0.0, mode='iso', axis=(0, -1, 0), k=1.0, spill=1.0,
                 excl=0.0, soft=0.05, B=0.0, r_m=0.0, r_px=None, glow=0.0, glow_r=5.0,
                 halo=0.0, halo_r=60.0, reflect=True, spikes=True, ztol=1.0, full=False):
        self.pos = np.array(pos, F)
        self.col = np.asarray(colr, F)
        self.I, self.mode, self.k, self.spill = float(I), mode, float(k), float(spill)
        a = np.array(axis, F)
        self.axis = a / np.linalg.norm(a)
        self.excl, self.soft = float(excl), float(soft)
        self.B, self.r_m, self.r_px = float(B), float(r_m), r_px
        self.glow, self.glow_r, self.halo, self.halo_r = float(glow), float(glow_r), float(halo), float(halo_r)
        self.reflect, self.spikes, self.ztol, self.full = reflect, spikes, float(ztol), full


class Scene:
    def __init__(self, rng, cam, kind):
        self.rng, self.cam, self.kind = rng, cam, kind
        self.Z = np.full((H, W), np.inf, F)
        self.L = np.zeros((H, W, 3), F)
        self.A = np.zeros((H, W, 3), F)
        self.X = np.zeros((H, W), F)
        self.Y = np.zeros((H, W), F)
        self.N = np.zeros((H, W), np.uint8)
        self.K = np.zeros((H, W), np.uint8)
        self.wet = np.zeros((H, W), F)
        self.emit = np.zeros((H, W, 3), F)      # neon (reflectable, not lit)
        self.trail = np.zeros((H, W, 3), F)     # light trails
        self.refl_pts = np.zeros((H, W, 3), F)  # mirrored point lights / trails
        self.lights = []
        self.texA = fbm(rng, H, W, 40, 5)
        self.texB = fbm(rng, H, W, 3, 2)
        self.texC = fbm(rng, H, W, 90, 3)
        self.refl_sx, self.refl_sy, self.ripple = 2.0, 30.0, 0.0
        self.haze = 0.0
        self.spikes = None
        self.amb_fill = None

    # -- G-buffer writes
    def write(self, sy, sx, t, nid, kind, L, A, wet=None):
        cam = self.cam
        self.Z[sy, sx] = t
        self.X[sy, sx] = cam.dx[sx] * t
        self.Y[sy, sx] = cam.hc + cam.dy[sy] * t
        self.N[sy, sx] = nid
        self.K[sy, sx] = kind
        self.L[sy, sx] = L
        self.A[sy, sx] = A
        self.wet[sy, sx] = 0.0 if wet is None else wet


# ----------------------------------------------------------------------------- primitives
def box_bbox(cam, bmin, bmax):
    if bmax[2] <= 0.05:
        return 0, 0, 0, 0
    xs, ys = [], []
    for X in (bmin[0], bmax[0]):
        for Y in (bmin[1], bmax[1]):
            for Z in (bmin[2], bmax[2]):
                if Z < 0.05:
                    return 0, H, 0, W
                x, y = cam.proj(X, Y, Z)
                xs.append(x)
                ys.append(y)
    x0 = max(0, int(math.floor(min(xs))) - 1)
    x1 = min(W, int(math.ceil(max(xs))) + 2)
    y0 = max(0, int(math.floor(min(ys))) - 1)
    y1 = min(H, int(math.ceil(max(ys))) + 2)
    return y0, y1, x0, x1


def paint_box(S, bmin, bmax, mat, kind=K_BUILD):
    cam = S.cam
    bmin = np.asarray(bmin, F)
    bmax = np.asarray(bmax, F)
    y0, y1, x0, x1 = box_bbox(cam, bmin, bmax)
    if y1 <= y0 or x1 <= x0:
        return
    dx = cam.dx[x0:x1][None, :]
    dy = cam.dy[y0:y1][:, None]
    a1, a2 = bmin[0] / dx, bmax[0] / dx
    txn, txf = np.minimum(a1, a2), np.maximum(a1, a2)
    b1, b2 = (bmin[1] - cam.hc) / dy, (bmax[1] - cam.hc) / dy
    tyn, tyf = np.minimum(b1, b2), np.maximum(b1, b2)
    tn = np.maximum(np.maximum(txn, tyn), bmin[2])
    tf = np.minimum(np.minimum(txf, tyf), bmax[2])
    hit = (tn <= tf) & (tn > 0.05) & (tn < S.Z[y0:y1, x0:x1])
    iy, ix = np.nonzero(hit)
    if iy.size == 0:
        return
    t = tn[iy, ix]
    txn_ = np.broadcast_to(txn, hit.shape)[iy, ix]
    tyn_ = np.broadcast_to(tyn, hit.shape)[iy, ix]
    sy, sx = iy + y0, ix + x0
    ddx, ddy = cam.dx[sx], cam.dy[sy]
    isx = txn_ >= np.maximum(tyn_, bmin[2])
    isy = (~isx) & (tyn_ >= bmin[2])
    nid = np.where(isx, np.where(ddx < 0, 2, 3), np.where(isy, np.where(ddy < 0, 1, 6), 4)).astype(np.uint8)
    X = ddx * t
    Y = cam.hc + ddy * t
    f = cam.f
    g = dict(sy=sy, sx=sx, t=t, nid=nid, X=X, Y=Y,
             u=np.where(isx, t, X), v=np.where(isy, t, Y),
             du=np.where(isx, t * t / (f * np.maximum(np.abs(X), 0.05)), t / f),
             dv=np.where(isy, t * t / (f * np.maximum(np.abs(Y - cam.hc), 0.05)), t / f),
             umin=np.where(isx, bmin[2], bmin[0]), umax=np.where(isx, bmax[2], bmax[0]),
             vmin=np.where(isy, bmin[2], bmin[1]), vmax=np.where(isy, bmax[2], bmax[1]),
             bmin=bmin, bmax=bmax)
    L, A = mat.shade(S, g)
    S.write(sy, sx, t, nid, kind, L, A)


def paint_ground(S, mat, zmax=30000.0):
    cam = S.cam
    y0 = int(max(0, math.floor(cam.yh)))
    if y0 >= H:
        return
    dy = cam.dy[y0:]
    rows = np.nonzero(dy < 0)[0]
    if rows.size == 0:
        return
    tcol = (-cam.hc / dy).astype(F)
    t = np.broadcast_to(tcol[:, None], (H - y0, W))
    hit = (dy[:, None] < 0) & (t < zmax) & (t < S.Z[y0:])
    iy, ix = np.nonzero(hit)
    t = t[iy, ix]
    sy, sx = iy + y0, ix
    X = cam.dx[sx] * t
    dX = t / cam.f
    dZ = t * t / (cam.f * cam.hc)
    L, A, wet = mat(S, X, t, dX, dZ, sy, sx)
    S.write(sy, sx, t, 1, K_GROUND, L, A, wet)


def paint_tree(S, X, Z, trunk_h, cw, chh, style, alb, amb, yb_m=0.0):
    """Billboard foliage (crown + trunk) at depth Z."""
    cam, rng = S.cam, S.rng
    if Z < 0.6:
        return
    f = cam.f
    cx, yb = cam.proj(X, yb_m, Z)
    _, ytop = cam.proj(X, yb_m + trunk_h + chh, Z)
    _, ycb = cam.proj(X, yb_m + trunk_h, Z)
    rxp = f * cw / 2 / Z
    ryp = (ycb - ytop) / 2
    if rxp < 0.6:
        return
    ycc = (ytop + ycb) / 2
    x0 = int(max(0, math.floor(cx - 1.6 * rxp)))
    x1 = int(min(W, math.ceil(cx + 1.6 * rxp) + 1))
    y0 = int(max(0, math.floor(ytop - 0.7 * ryp)))
    y1 = int(min(H, math.ceil(yb) + 1))
    if x1 <= x0 or y1 <= y0:
        return
    h, w = y1 - y0, x1 - x0
    xx = (np.arange(x0, x1, dtype=F) + 0.5)[None, :]
    yy = (np.arange(y0, y1, dtype=F) + 0.5)[:, None]
    nx = (xx - cx) / rxp
    ny = (yy - ycc) / max(ryp, 0.5)
    n1 = np.clip(fbm(rng, h, w, max(2.0, rxp / 3), 3), -1.6, 1.6)
    n2 = np.clip(fbm(rng, h, w, float(np.clip(rxp / 14, 1.5, 4.0)), 2), -2, 2)
    if style == 'conifer':
        half = 0.5 * (ny + 1) * (1 + 0.18 * n1) + 0.04 + 0.12 * np.abs(np.sin((ny + 1) * 7.0)) * (ny + 1) * 0.5
        crown = (np.abs(nx) < half) & (ny > -1.05) & (ny < 1.0)
    elif style == 'hedge':
        crown = (np.abs(nx) < 1.0 + 0.05 * n1) & (ny > -1.0 + 0.25 * n1) & (ny < 1.2)
    else:
        r = np.sqrt(nx * nx + ny * ny)
        crown = (r + 0.3 * n1 + 0.06 * n2 < 1.0) & ~((n2 + 0.4 * n1 > 1.6) & (r < 0.9))
    tw = max(0.55, f * 0.13 / Z)
    trunk = (np.abs(xx - cx) < tw) & (yy > ycc) & (yy <= yb)
    m = crown | trunk
    m &= Z < S.Z[y0:y1, x0:x1]
    iy, ix = np.nonzero(m)
    if iy.size == 0:
        return
    sy, sx = iy + y0, ix + x0
    isc = crown[iy, ix]
    nid = np.where(isc, 7, 4).astype(np.uint8)
    shade = np.clip(0.65 + 0.35 * n2[iy, ix], 0.25, 1.3)
    a = np.where(isc[:, None], alb[None, :] * shade[:, None], col(0.09, 0.07, 0.05)[None, :] * shade[:, None])
    S.write(sy, sx, np.full(iy.size, Z, F), nid, K_FOLIAGE, a * amb, a)


def world_noise(S, X, Z, dX, dZ, scale_m=6.0):
    """fBm tile (64 px / tile, wraps) sampled at ground coords; fades to 0 where footprint is coarse."""
    if not hasattr(S, '_wtile'):
        t = fbm(S.rng, 256, 256, 32, 4)
        t = np.concatenate([t, t[:, :1]], 1)
        t = np.concatenate([t, t[:1, :]], 0)
        S._wtile = t
    ppm = 256.0 / (4 * scale_m)            # tile spans 4*scale_m metres
    mx = ((X * ppm) % 256).astype(F)
    my = ((Z * ppm) % 256).astype(F)
    ix, iy = np.minimum(mx.astype(np.int64), 255), np.minimum(my.astype(np.int64), 255)
    fx, fy = mx - ix, my - iy
    t = S._wtile
    v = ((t[iy, ix] * (1 - fx) + t[iy, ix + 1] * fx) * (1 - fy)
         + (t[iy + 1, ix] * (1 - fx) + t[iy + 1, ix + 1] * fx) * fy)
    fade = np.clip(1.5 - np.maximum(dX, dZ) * ppm / 8.0, 0, 1)
    return v * fade


# ----------------------------------------------------------------------------- materials
class Plain:
    def __init__(self, alb, amb, tex=0.2, emit=None, emit_nid=None):
        self.alb = np.asarray(alb, F)
        self.amb, self.tex, self.emit, self.emit_nid = float(amb), float(tex), emit, emit_nid

    def shade(self, S, g):
        sy, sx = g['sy'], g['sx']
        tx = 0.6 * S.texA[sy, sx] + 0.4 * S.texB[sy, sx]
        a = self.alb[None, :] * np.clip(1 + self.tex * tx, 0.2, 3)[:, None]
        L = a * self.amb
        if self.emit is not None:
            m = np.ones(sy.size, bool) if self.emit_nid is None else (g['nid'] == self.emit_nid)
            L[m] += self.emit
        return L, a


class Screen:
    """Box with one emissive face showing a blurry picture (TV / monitor)."""
    def __init__(self, rng, face_nid, level, tint):
        self.face, self.level = face_nid, level
        lumi = rng.random((6, 9, 1)).astype(F) ** 1.5
        hue = 0.75 + 0.25 * rng.random((6, 9, 3)).astype(F) * pick(
            rng, [col(1, 0.8, 0.6), col(0.6, 0.8, 1), col(0.7, 1, 0.7)])
        img = cv2.resize(lumi * hue, (90, 60), interpolation=cv2.INTER_CUBIC)
        self.img = np.clip(cv2.GaussianBlur(img, (0, 0), 2), 0.02, 1) * np.asarray(tint, F)
        self.case = col(0.02, 0.02, 0.02)

    def shade(self, S, g):
        n = g['sy'].size
        L = np.zeros((n, 3), F)
        A = np.tile(self.case, (n, 1))
        m = g['nid'] == self.face
        uu = (g['u'][m] - g['umin'][m]) / np.maximum(g['umax'][m] - g['umin'][m], 1e-3)
        vv = (g['vmax'][m] - g['v'][m]) / np.maximum(g['vmax'][m] - g['vmin'][m], 1e-3)
        inner = (uu > 0.04) & (uu < 0.96) & (vv > 0.06) & (vv < 0.94)
        if self.face == 2:
            uu = 1 - uu
        px = np.clip((uu * 89).astype(int), 0, 89)
        py = np.clip((vv * 59).astype(int), 0, 59)
        L[m] = np.where(inner[:, None], self.img[py, px] * self.level, 0.0)
        A[m] = np.where(inner[:, None], 0.02, A[m])
        return L, A


class Facade:
    """Building surface with a window grid (lit windows: 0.3-5, some off, blinds, curtains)."""
    def __init__(self, rng, style=None, downtown=False, amb=None, shops=None, lit_p=None):
        self.style = style or pick(rng, ['home', 'home', 'brick', 'office', 'glass', 'old'])
        st = self.style
        base = {'home': col(0.36, 0.31, 0.26), 'brick': col(0.30, 0.14, 0.09), 'office': col(0.26, 0.26, 0.25),
                'glass': col(0.06, 0.07, 0.09), 'old': col(0.32, 0.28, 0.22)}[st]
        self.alb = np.clip(base * U(rng, 0.5, 1.25) * col(*rng.uniform(0.9, 1.1, 3)), 0.02, 0.6)
        self.amb = amb if amb is not None else LU(rng, 0.02, 0.12)
        if st == 'glass':
            self.amb = LU(rng, 0.1, 0.4)
        office = st in ('office', 'glass')
        self.office = office
        self.floor_h = U(rng, 3.5, 4.2) if office else U(rng, 2.8, 3.5)
        self.pitch = U(rng, 1.5, 3.0) if office else U(rng, 2.2, 4.5)
        if office and chance(rng, 0.6):
            self.ww, self.wh = U(rng, 0.85, 0.97), U(rng, 0.55, 0.85)
        else:
            self.ww, self.wh = U(rng, 0.3, 0.7), U(rng, 0.35, 0.62)
        self.wx0 = (1 - self.ww) / 2
        self.wy0 = U(rng, 0.1, 0.95 - self.wh) if self.wh < 0.85 else 0.05
        self.lit_p = lit_p if lit_p is not None else (U(rng, 0.08, 0.6) if office else U(rng, 0.15, 0.7))
        self.pal = (PAL_OFFICE if office else PAL_HOME) * rng.uniform(0.5, 1.5, 7)
        self.pal = (self.pal / self.pal.sum()).astype(F)
        self.cpal = np.cumsum(self.pal)
        self.b_lo, self.b_hi, self.b_gam = 0.3, U(rng, 2.0, 5.0), U(rng, 1.0, 2.2)
        self.blinds_p = U(rng, 0.0, 0.5)
        self.curtain_p = 0.0 if office else U(rng, 0.0, 0.4)
        self.edge = U(rng, 0.4, 1.6)
        self.top_margin = U(rng, 0.5, 1.5)
        self.salt = int(rng.integers(1, 2 ** 30))
        self.tex = U(rng, 0.1, 0.35)
        self.shops = chance(rng, 0.5 if downtown else 0.25) if shops is None else shops
        self.gf = U(rng, 3.6, 5.0) if self.shops else 0.0
        self.shop_pitch = U(rng, 4.0, 9.0)
        self.shop_lit = U(rng, 0.3, 0.9)
        self.shop_mull = float(rng.integers(2, 5))
        self.shop_col = pick(rng, [col(1.0, 0.85, 0.65), col(0.95, 0.98, 1.0), col(1.0, 0.75, 0.5)])
        self.glass = self.alb * self.amb * 0.4 + col(0.6, 0.7, 1.0) * U(rng, 0.001, 0.006)
        bs = self.b_lo * (self.b_hi / self.b_lo) ** (np.linspace(0, 1, 257) ** self.b_gam)
        self.mean_lit = (float(bs.mean()) * (self.pal @ WINDOW_PAL) * (1 - 0.4 * self.blinds_p)).astype(F)

    def shade(self, S, g):
        sy, sx, nid = g['sy'], g['sx'], g['nid']
        tx = 0.55 * S.texA[sy, sx] + 0.45 * S.texB[sy, sx]
        a = self.alb[None, :] * np.clip(1 + self.tex * tx, 0.25, 2.5)[:, None]
        L = a * self.amb * np.clip(1 + 0.15 * S.texC[sy, sx], 0.5, 1.5)[:, None]
        wall = (nid >= 2) & (nid <= 5)
        if not wall.any():
            return L, a
        wi = np.nonzero(wall)[0]
        u, v, du, dv = g['u'][wi], g['v'][wi], g['du'][wi], g['dv'][wi]
        umin, umax, vmin, vmax = g['umin'][wi], g['umax'][wi], g['vmin'][wi], g['vmax'][wi]
        salt = self.salt + 1000 * nid[wi].astype(np.int64)
        # upper floors
        fh, pitch = self.floor_h, self.pitch
        vv = v - vmin - self.gf
        nfl = np.floor((vmax - vmin - self.gf - self.top_margin) / fh)
        Vf = vv / fh
        lenu = umax - umin
        ncol = np.floor(np.maximum(lenu - 2 * self.edge, 0) / pitch)
        Uf = (u - (umin + (lenu - ncol * pitch) / 2)) / pitch
        cov = box_cov(Uf, du / pitch, self.wx0, self.ww) * box_cov(Vf, dv / fh, self.wy0, self.wh)
        cov *= (Uf >= 0) & (Uf < ncol) & (Vf >= 0) & (Vf < nfl)
        iu, iv = np.floor(Uf).astype(np.int64), np.floor(Vf).astype(np.int64)
        h1, h2, h3 = hash01(iu, iv, salt + 1), hash01(iu, iv, salt + 2), hash01(iu, iv, salt + 3)
        h4, h5 = hash01(iu, iv, salt + 4), hash01(iu, iv, salt + 5)
        if self.office:
            lit = (hash01(iv, 0, salt + 9) < self.lit_p * 1.3) & (h1 < 0.9)
        else:
            lit = h1 < self.lit_p * (0.55 + 0.9 * hash01(iv, 1, salt + 9))
        b = self.b_lo * (self.b_hi / self.b_lo) ** (h2 ** self.b_gam)
        ci = np.searchsorted(self.cpal, h3 * self.cpal[-1]).clip(0, len(WINDOW_PAL) - 1)
        e = WINDOW_PAL[ci] * b[:, None]
        fu = np.clip((Uf - iu - self.wx0) / self.ww, 0, 1)
        fv = np.clip((Vf - iv - self.wy0) / self.wh, 0, 1)   # 0 = bottom of window
        e *= (0.7 + 0.5 * fv)[:, None]                        # ceiling light -> brighter top
        blinds = h4 < self.blinds_p
        nst = 6 + (h4 * 37 % 8).astype(np.int64)
        pv = dv / (fh * self.wh) * nst
        stripe = 0.5 + 0.5 * np.cos(2 * np.pi * fv * nst) * np.clip(1.5 - 2 * pv, 0, 1)
        e *= np.where(blinds, 0.25 + 0.75 * stripe, 1.0)[:, None]
        curt = (h5 < self.curtain_p) & ((fu < 0.25 + 0.2 * h5) | (fu > 0.75 - 0.2 * h5))
        e *= np.where(curt, 0.3, 1.0)[:, None]
        em = np.where(lit[:, None], e, self.glass[None, :])
        mean_em = self.lit_p * self.mean_lit + (1 - self.lit_p) * self.glass
        tb = np.clip((np.maximum(du / pitch, dv / fh) - 0.3) / 0.7, 0, 1)[:, None]
        em = em * (1 - tb) + mean_em[None, :] * tb
        Lw, aw = L[wi], a[wi]
        Lw = Lw * (1 - cov[:, None]) + em * cov[:, None]
        aw = aw * (1 - cov[:, None]) + 0.03 * cov[:, None]
        # ground-floor shops
        if self.gf > 0:
            vs = v - vmin
            sh = vs < self.gf
            if sh.any():
                Us = (u - umin) / self.shop_pitch
                cs = box_cov(Us, du / self.shop_pitch, 0.08, 0.84) * interval_cov(vs, dv, 0.35, self.gf * 0.82)
                isu = np.floor(Us).astype(np.int64)
                hs = hash01(isu, 7, salt + 11)
                slit = hs < self.shop_lit
                lev = 0.8 * (5.0 / 0.8) ** hash01(isu, 8, salt + 12)
                grad = np.clip(1.15 - 0.4 * vs / self.gf, 0.5, 1.2)
                # display contents / shelves (dark blobs) and window mullions
                cont = 0.35 + 0.65 * smoothstep(-0.8, 0.6, S.texA[sy[wi], sx[wi]] * 1.3 + 0.5 * S.texB[sy[wi], sx[wi]])
                fus = Us - isu
                mul = 1 - box_cov(fus * self.shop_mull, du / self.shop_pitch * self.shop_mull, 0, 0.04)
                shelf = 1 - 0.5 * box_cov(vs / 0.45, dv / 0.45, 0, 0.06) * (hash01(isu, 10, salt + 14) < 0.5)
                se = np.where(slit[:, None], self.shop_col[None, :] * (lev * grad * cont * mul * shelf)[:, None],
                              self.glass[None, :] * 0.7)
                shutter = (~slit) & (hash01(isu, 9, salt + 13) < 0.5)
                sa = np.where(shutter[:, None], 0.22, 0.03)
                sl = np.where(shutter[:, None], (0.22 * self.amb) * (0.8 + 0.2 * np.cos(vs * 60))[:, None], se)
                csh = (cs * sh)[:, None]
                Lw = np.where(sh[:, None], Lw * (1 - csh) + sl * csh, Lw)
                aw = np.where(sh[:, None], aw * (1 - csh) + sa * csh, aw)
        L[wi], a[wi] = Lw, aw
        return L, a


# ----------------------------------------------------------------------------- lighting
def light_bbox(S, Lt, eps=2e-3):
    if Lt.full or S.kind == 'interior':
        return 0, H, 0, W, 1e9
    px, py, pz = [float(v) for v in Lt.pos]
    if Lt.mode == 'dir' and Lt.axis[1] < -0.7:
        R = max(math.sqrt(Lt.I * max(Lt.spill, 1e-4) / eps),
                (Lt.I * max(py, 0.5) ** (Lt.k + 1) / eps) ** (1.0 / (Lt.k + 3)))
    else:
        R = math.sqrt(Lt.I / eps)
    R = min(R, 3000.0)
    y0, y1, x0, x1 = box_bbox(S.cam, (px - R, py - R, pz - R), (px + R, py + R, pz + R))
    return y0, y1, x0, x1, R


def light_pass(S):
    E = np.zeros((H, W, 3), F)
    litmask = S.N != 0
    for Lt in S.lights:
        if Lt.I <= 0:
            continue
        y0, y1, x0, x1, R = light_bbox(S, Lt)
        if y1 <= y0 or x1 <= x0:
            continue
        iy, ix = np.nonzero(litmask[y0:y1, x0:x1])
        if iy.size == 0:
            continue
        sy, sx = iy + y0, ix + x0
        px, py, pz = Lt.pos
        vx = S.X[sy, sx] - px
        vy = S.Y[sy, sx] - py
        vz = S.Z[sy, sx] - pz
        d2 = vx * vx + vy * vy + vz * vz
        inv = 1.0 / np.sqrt(d2 + 1e-8)
        nid = S.N[sy, sx]
        nv = NORM[nid]
        cos = -(nv[:, 0] * vx + nv[:, 1] * vy + nv[:, 2] * vz) * inv
        cos = np.where(nid == 7, 0.5, np.maximum(cos, 0))
        if Lt.mode == 'dir':
            a = Lt.axis
            lobe = Lt.spill + (1 - Lt.spill) * np.maximum((vx * a[0] + vy * a[1] + vz * a[2]) * inv, 0) ** Lt.k
        elif Lt.mode == 'updown':
            lobe = Lt.spill + (1 - Lt.spill) * np.abs(vy * inv) ** Lt.k
        else:
            lobe = 1.0
        e = Lt.I * cos * lobe / np.maximum(d2, Lt.soft * Lt.soft)
        if R < 1e8:
            e *= np.clip(1 - d2 / (R * R), 0, 1) ** 2
        if Lt.excl > 0:
            e[d2 < Lt.excl * Lt.excl] = 0
        E[sy, sx] += e[:, None] * Lt.col[None, :]
    return E


# ----------------------------------------------------------------------------- emissive drawing
def _patch(x, y, rad):
    x0, x1 = int(math.floor(x - rad)), int(math.ceil(x + rad)) + 1
    y0, y1 = int(math.floor(y - rad)), int(math.ceil(y + rad)) + 1
    x0, x1, y0, y1 = max(0, x0), min(W, x1), max(0, y0), min(H, y1)
    return x0, x1, y0, y1


def add_glow(img, x, y, peak, colr, r1, halo=0.0, rh=60.0):
    if peak <= 0:
        return
    Rp = r1 * math.log(max(peak, 1e-3) / 2e-4 + 1) + 2
    Rp = min(max(Rp, 3 * r1), 450)
    if halo > 0:
        Rh = min(max(rh * math.log(max(peak * halo, 1e-5) / 2e-4 + 1), 3), 480)
        Rp = max(Rp, Rh)
    x0, x1, y0, y1 = _patch(x, y, Rp)
    if x1 <= x0 or y1 <= y0:
        return
    xx = (np.arange(x0, x1, dtype=F) + 0.5 - x)[None, :]
    yy = (np.arange(y0, y1, dtype=F) + 0.5 - y)[:, None]
    d2 = xx * xx + yy * yy
    d = np.sqrt(d2)
    prof = 0.7 * np.exp(-d / r1) + 0.3 * np.exp(-d2 / (2 * (0.5 * r1) ** 2))
    if halo > 0:
        prof = prof + halo * np.exp(-d / rh)
    prof *= np.clip(1 - d2 / (Rp * Rp), 0, 1) ** 2
    img[y0:y1, x0:x1] += (peak * prof)[:, :, None] * colr[None, None, :]


def add_spikes(img, x, y, amp, length, nsp, ang0, colr):
    x0, x1, y0, y1 = _patch(x, y, length + 2)
    if x1 <= x0 or y1 <= y0:
        return
    xx = (np.arange(x0, x1, dtype=F) + 0.5 - x)[None, :]
    yy = (np.arange(y0, y1, dtype=F) + 0.5 - y)[:, None]
    acc = np.zeros((y1 - y0, x1 - x0), F)
    for i in range(nsp):
        th = ang0 + 2 * math.pi * i / nsp
        c, s = math.cos(th), math.sin(th)
        along = xx * c + yy * s
        perp = -xx * s + yy * c
        acc += np.exp(-0.5 * (perp / 0.7) ** 2) * np.clip(1 - along / length, 0, 1) ** 2 * (along > 0.5)
    img[y0:y1, x0:x1] += (amp * acc)[:, :, None] * colr[None, None, :]


def core_geom(S, Lt, mirror=False, pos=None):
    cam = S.cam
    X, Y, Z = [float(v) for v in (Lt.pos if pos is None else pos)]
    if mirror:
        Y = -Y
    if Z < 0.1:
        return None
    x, y = cam.proj(X, Y, Z)
    r = Lt.r_px if Lt.r_px is not None else cam.f * Lt.r_m / Z
    B = Lt.B
    if r < 1.0:
        B = max(B * max(r, 0.3) ** 2, min(B, 20.0))
        r = 1.0
    r = min(r, 6.0)
    return x, y, r, B, Z


def draw_light(S, img, Lt, mirror=False, scale=1.0, pos=None, ztest=True):
    cg = core_geom(S, Lt, mirror, pos)
    if cg is None or Lt.B <= 0:
        return
    x, y, r, B, Z = cg
    B *= scale
    rad = r + 2
    if -60 < x < W + 60 and -60 < y < H + 60:
        visf = 1.0
        x0, x1, y0, y1 = _patch(x, y, rad)
        if x1 > x0 and y1 > y0:
            xx = (np.arange(x0, x1, dtype=F) + 0.5 - x)[None, :]
            yy = (np.arange(y0, y1, dtype=F) + 0.5 - y)[:, None]
            d = np.sqrt(xx * xx + yy * yy)
            cov = np.clip(r + 0.5 - d, 0, 1)
            if ztest and not mirror:
                vis = S.Z[y0:y1, x0:x1] > Z - Lt.ztol
                cv = cov * vis
                visf = float(cv.sum() / max(cov.sum(), 1e-6))
                cov = cv
            img[y0:y1, x0:x1] += (cov * B)[:, :, None] * Lt.col[None, None, :]
        if Lt.glow > 0:
            gscale = 0.6 if mirror else 1.0
            add_glow(img, x, y, Lt.glow * B * math.sqrt(visf), Lt.col, Lt.glow_r * gscale * (0.9 + 0.1 * r),
                     Lt.halo if not mirror else 0.0, Lt.halo_r)
        if (not mirror) and S.spikes is not None and Lt.spikes and visf > 0.3:
            energy = B * r * r
            if energy > S.spikes['thr']:
                nsp, ang, a = S.spikes['n'], S.spikes['ang'], S.spikes['amp']
                length = min(20 + 22 * math.log10(energy / S.spikes['thr'] + 1) * S.spikes['len'], 260)
                add_spikes(img, x, y, a * B * visf, length, nsp, ang, Lt.col)


def draw_polyline3d(S, pts, colr, val, width_m=0.12, maxpx=4, reflect=True, gap_fn=None):
    """Light trail: thin emissive polyline in 3D (thickness from distance), depth tested."""
    cam = S.cam
    pts = np.asarray(pts, F)
    pts = pts[pts[:, 2] > 0.3]
    if len(pts) < 2:
        return
    for mirror in ([False, True] if reflect else [False]):
        Y = -pts[:, 1] if mirror else pts[:, 1]
        x = cam.xv + cam.f * pts[:, 0] / pts[:, 2]
        y = cam.yh + cam.f * (cam.hc - Y) / pts[:, 2]
        if (x.max() < -10) or (x.min() > W + 10) or (y.max() < -10) or (y.min() > H + 10):
            continue
        mask = np.zeros((H, W), np.uint8)
        depth = np.full((H, W), np.inf, F)
        for i in range(len(pts) - 1):
            if gap_fn is not None and gap_fn(i):
                continue
            zm = 0.5 * (pts[i, 2] + pts[i + 1, 2])
            th = int(np.clip(round(cam.f * width_m / zm), 1, maxpx))
            p0 = (int(round(x[i] * 16)), int(round(y[i] * 16)))
            p1 = (int(round(x[i + 1] * 16)), int(round(y[i + 1] * 16)))
            if max(abs(p0[0]), abs(p0[1]), abs(p1[0]), abs(p1[1])) > 16 * 30000:
                continue
            cv2.line(mask, p0, p1, 255, th, cv2.LINE_AA, 4)
            if not mirror:
                cv2.line(depth, p0, p1, float(zm), th + 2, cv2.LINE_8, 4)
        m = mask.astype(F) / 255.0
        if mirror:
            S.refl_pts += (m * val)[:, :, None] * colr[None, None, :]
        else:
            vis = S.Z >= depth - 1.5
            S.trail += (m * vis * val)[:, :, None] * colr[None, None, :]


def neon_canvases(rng, w_m, h_m, ppm, vertical=False):
    ppm = float(np.clip(ppm, 4, 120))
    cw = int(np.clip(w_m * ppm, 8, 900))
    ch = int(np.clip(h_m * ppm, 8, 900))
    th = int(np.clip(round(ppm * 0.05), 1, 3))
    c1 = np.zeros((ch, cw), np.uint8)
    word = pick(rng, WORDS)
    font = pick(rng, FONTS)
    if vertical:
        n = len(word)
        cell = ch / n
        for i, chh in enumerate(word):
            (tw, tht), _ = cv2.getTextSize(chh, font, 1.0, th)
            sc = min(0.8 * cw / max(tw, 1), 0.75 * cell / max(tht, 1))
            org = (int((cw - tw * sc) / 2), int(i * cell + (cell + tht * sc) / 2))
            cv2.putText(c1, chh, org, font, sc, 255, th, cv2.LINE_AA)
    else:
        (tw, tht), _ = cv2.getTextSize(word, font, 1.0, th)
        sc = min(0.86 * cw / max(tw, 1), 0.62 * ch / max(tht, 1))
        org = (int((cw - tw * sc) / 2), int((ch + tht * sc) / 2))
        cv2.putText(c1, word, org, font, sc, 255, th, cv2.LINE_AA)
    out = [(c1, 0)]
    c2 = np.zeros_like(c1)
    r = rng.random()
    if r < 0.45:
        m = th + 1
        cv2.rectangle(c2, (m, m), (cw - 1 - m, ch - 1 - m), 255, th, cv2.LINE_AA)
        out.append((c2, 1))
    elif r < 0.65 and not vertical:
        yb = int(ch * 0.9)
        cv2.line(c2, (int(cw * 0.1), yb), (int(cw * 0.9), yb), 255, th, cv2.LINE_AA)
        out.append((c2, 1))
    elif r < 0.8 and not vertical:   # wavy underline / arrow
        xs = np.linspace(0.08 * cw, 0.92 * cw, 40)
        ys = ch * 0.88 + ch * 0.05 * np.sin(xs / cw * 18)
        pts = np.stack([xs, ys], 1).astype(np.int32)
        cv2.polylines(c2, [pts], False, 255, th, cv2.LINE_AA)
        out.append((c2, 1))
    return out


def add_neon_sign(S, corners, vertical=False, ncol=None, val=None):
    """corners: 4x3 world points TL, TR, BR, BL of the sign plane."""
    cam, rng = S.cam, S.rng
    c = np.asarray(corners, F)
    if (c[:, 2] < 0.8).any():
        return
    xs = cam.xv + cam.f * c[:, 0] / c[:, 2]
    ys = cam.yh + cam.f * (cam.hc - c[:, 1]) / c[:, 2]
    x0, x1 = int(max(0, math.floor(xs.min()) - 2)), int(min(W, math.ceil(xs.max()) + 3))
    y0, y1 = int(max(0, math.floor(ys.min()) - 2)), int(min(H, math.ceil(ys.max()) + 3))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return
    w_m = float(np.linalg.norm(c[1] - c[0]))
    h_m = float(np.linalg.norm(c[3] - c[0]))
    zmid = float(c[:, 2].mean())
    ppm = cam.f / zmid
    cans = neon_canvases(rng, w_m, h_m, ppm, vertical)
    ch, cw = cans[0][0].shape
    src = np.array([[0, 0], [cw, 0], [cw, ch], [0, ch]], np.float32)
    dst = np.stack([xs - x0, ys - y0], 1).astype(np.float32)
    M = cv2.getPerspectiveTransform(src, dst)
    keys = list(NEON.keys())
    cols = [NEON[ncol] if ncol else NEON[pick(rng, keys)], NEON[pick(rng, keys)]]
    vis = S.Z[y0:y1, x0:x1] > float(c[:, 2].min()) - 0.4
    for can, ci in cans:
        wm = cv2.warpPerspective(can.astype(F) / 255.0, M, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR)
        v = val if val is not None else LU(rng, 2.0, 50.0)
        S.emit[y0:y1, x0:x1] += (wm * vis * v)[:, :, None] * cols[ci][None, None, :]


# ----------------------------------------------------------------------------- sky
def sky_params(rng, city=True):
    if city:
        glow_c = pick(rng, [col(1.0, 0.6, 0.3), col(1.0, 0.72, 0.5), col(0.75, 0.8, 1.0), col(0.9, 0.75, 0.8)])
        P = dict(hor=glow_c * LU(rng, 0.006, 0.018), zen=col(0.35, 0.42, 0.75) * LU(rng, 0.0025, 0.006),
                 stars=int(LU(rng, 15, 200)), clouds=U(rng, 0.3, 1.0) if chance(rng, 0.5) else 0.0,
                 cloud_gain=U(rng, 1.3, 2.2), moon=chance(rng, 0.3))
    else:
        glow_c = pick(rng, [col(0.5, 0.6, 1.0), col(0.9, 0.7, 0.5), col(0.6, 0.65, 0.9)])
        P = dict(hor=glow_c * LU(rng, 0.003, 0.012), zen=col(0.3, 0.4, 0.85) * LU(rng, 0.0025, 0.005),
                 stars=int(LU(rng, 300, 1500)), clouds=U(rng, 0.2, 0.8) if chance(rng, 0.4) else 0.0,
                 cloud_gain=U(rng, 0.6, 1.3), moon=chance(rng, 0.6))
    P['h0'] = U(rng, 0.08, 0.3)
    P['thr'] = U(rng, 0.0, 0.9)
    return P


def sky_base(dy, P):
    e = np.maximum(dy, 0)
    g = np.exp(-e / P['h0'])[..., None]
    g2 = np.exp(-e / 0.8)[..., None]
    return P['zen'] * (1 - g) + P['hor'] * g * 0.8 + P['hor'] * 0.2 * g2


def paint_sky(S, P):
    cam, rng = S.cam, S.rng
    sky = ~np.isfinite(S.Z)
    if not sky.any():
        return
    dyy = np.broadcast_to(cam.dy[:, None], (H, W))
    base = sky_base(dyy, P).astype(F)
    cov = np.zeros((H, W), F)
    if P['clouds'] > 0:
        cl = fbm(rng, H, W // 3 + 2, 60, 5)
        cl = cv2.resize(cl, (W, H), interpolation=cv2.INTER_LINEAR)
        cov = smoothstep(P['thr'] - 0.2, P['thr'] + 0.6, cl) * P['clouds']
        gain = 1 + (P['cloud_gain'] - 1) * np.exp(-np.maximum(dyy, 0) / 0.35)
        base = base * (1 - cov[..., None]) + base * (gain * (0.85 + 0.15 * S.texB))[..., None] * cov[..., None]
    out = base
    # moon
    if P['moon']:
        for _ in range(20):
            mx = U(rng, 60, W - 60)
            my = U(rng, 40, max(50.0, min(cam.yh - 60, H * 0.55)))
            if 0 <= int(my) < H and sky[int(my), int(mx)]:
                break
        else:
            mx = None
        if mx is not None:
            rm = U(rng, 6, 22)
            skyv = float(base[int(my), int(mx)] @ LUMW)
            Bm = max(skyv, 0.001) * LU(rng, 100, 2000)
            mcol = pick(rng, [col(1.0, 0.97, 0.9), col(1.0, 0.92, 0.78), col(0.95, 0.97, 1.0)])
            x0, x1, y0, y1 = _patch(mx, my, 500)
            xx = (np.arange(x0, x1, dtype=F) + 0.5 - mx)[None, :]
            yy = (np.arange(y0, y1, dtype=F) + 0.5 - my)[:, None]
            d = np.sqrt(xx * xx + yy * yy)
            disc = np.clip(rm + 0.5 - d, 0, 1)
            if chance(rng, 0.5):  # phase
                sh = U(rng, 0.4, 1.6) * rm
                ang = U(rng, 0, 2 * math.pi)
                d2 = np.sqrt((xx - sh * math.cos(ang)) ** 2 + (yy - sh * math.sin(ang)) ** 2)
                lit = disc * np.clip(d2 - rm + 0.5, 0, 1)
            else:
                lit = disc
            ph = float(lit.sum() / max(disc.sum(), 1))
            tex = 0.82 + 0.18 * np.clip(fbm(rng, y1 - y0, x1 - x0, max(2, rm / 3), 3), -1, 1)
            limb = 1 - 0.25 * np.clip(d / rm, 0, 1) ** 2
            moon = Bm * (lit * tex * limb + 0.003 * disc)
            halo = Bm * ph * (U(rng, 0.004, 0.02) * np.exp(-np.maximum(d - rm, 0) / U(rng, 15, 60)) +
                              U(rng, 0.0005, 0.002) * np.exp(-d / 220.0)) * (1 - disc)
            cc = cov[y0:y1, x0:x1]
            halo = halo * (1 + 2.5 * cc)
            moon = moon * (1 - 0.85 * cc)
            out[y0:y1, x0:x1] += (moon + halo)[:, :, None] * mcol[None, None, :]
    # stars (single pixels)
    n = P['stars']
    if n > 0:
        ys = rng.integers(0, max(1, int(min(H, cam.yh))), n * 2)
        xs = rng.integers(0, W, n * 2)
        ok = sky[ys, xs] & (cov[ys, xs] < 0.35)          # hidden behind clouds
        ys, xs = ys[ok][:n], xs[ok][:n]
        if ys.size:
            ext = np.clip(cam.dy[ys] / 0.12, 0.25, 1.0)       # fainter near the horizon
            b = np.clip(0.5 * rng.random(ys.size) ** (-1 / 1.6) * ext, 0.5, 20.0)
            tint = np.stack([rng.uniform(0.8, 1.0, ys.size), rng.uniform(0.85, 1.0, ys.size),
                             rng.uniform(0.8, 1.0, ys.size)], 1).astype(F)
            np.add.at(out, (ys, xs), (b[:, None] * tint).astype(F))
    S.L[sky] = out[sky]
    S.N[sky] = 0
    S.K[sky] = K_SKY


# ----------------------------------------------------------------------------- street pieces
def add_street_lamp(S, Xp, Z, Hl, arm, colr, B, I, k, spill, glow, glow_r, halo, halo_r, r_m, style='arm'):
    pole = Plain(col(0.09, 0.09, 0.1), 0.02, 0.1)
    pw = 0.07
    if Z < 0.5:
        return
    if style == 'post':  # park/pedestrian lantern or globe
        paint_box(S, (Xp - pw, 0, Z - pw), (Xp + pw, Hl - 0.25, Z + pw), pole, K_FIXT)
        lx = Xp
        ly = Hl
        paint_box(S, (Xp - 0.18, Hl + 0.22, Z - 0.18), (Xp + 0.18, Hl + 0.3, Z + 0.18), pole, K_FIXT)
        lt = Light((lx, ly, Z), colr, I=I, mode='iso', excl=0.45, B=B, r_m=r_m, glow=glow, glow_r=glow_r,
                   halo=halo, halo_r=halo_r)
    else:
        paint_box(S, (Xp - pw, 0, Z - pw), (Xp + pw, Hl + 0.1, Z + pw), pole, K_FIXT)
        lx = Xp + arm
        a0, a1 = min(Xp, lx), max(Xp, lx)
        paint_box(S, (a0, Hl + 0.02, Z - 0.04), (a1, Hl + 0.1, Z + 0.04), pole, K_FIXT)
        paint_box(S, (lx - 0.35, Hl + 0.03, Z - 0.15), (lx + 0.35, Hl + 0.16, Z + 0.15), pole, K_FIXT)
        lt = Light((lx, Hl - 0.03, Z), colr, I=I, mode='dir', axis=(0, -1, 0), k=k, spill=spill, excl=0.6,
                   B=B, r_m=r_m, glow=glow, glow_r=glow_r, halo=halo, halo_r=halo_r)
    S.lights.append(lt)
    return lt


def add_car(S, X, Z, facing, headlights_on=True, lights_B=None, I_head=None):
    """facing=-1: front towards camera (headlights), +1: rear towards camera (taillights)."""
    rng = S.rng
    if Z < 2.0:
        return
    paint_col = pick(rng, [col(0.5, 0.5, 0.5), col(0.05, 0.05, 0.05), col(0.4, 0.05, 0.04), col(0.08, 0.12, 0.3),
                           col(0.55, 0.55, 0.58), col(0.2, 0.2, 0.22), col(0.5, 0.45, 0.3)])
    body = Plain(paint_col * U(rng, 0.35, 0.7), 0.03, 0.1)
    glass = Plain(col(0.02, 0.02, 0.025), 0.03, 0.05)
    L_ = U(rng, 4.0, 4.8)
    wd = U(rng, 0.85, 0.95)
    z0, z1 = Z, Z + L_
    paint_box(S, (X - wd, 0.28, z0), (X + wd, 0.95, z1), body, K_OBJ)
    paint_box(S, (X - wd + 0.08, 0.95, z0 + 1.1), (X + wd - 0.08, U(rng, 1.38, 1.55), z1 - 0.8), glass, K_OBJ)
    paint_box(S, (X - wd + 0.05, 0.0, z0 + 0.6), (X + wd - 0.05, 0.3, z1 - 0.6),
              Plain(col(0.02, 0.02, 0.02), 0.02), K_OBJ)
    if not headlights_on:
        return
    if facing < 0:
        B = lights_B if lights_B else LU(rng, 50, 5000)
        c = pick(rng, [col(1.0, 0.97, 0.92), col(0.9, 0.95, 1.0), col(1.0, 0.88, 0.7)])
        glow = LU(rng, 0.005, 0.05)
        gr = U(rng, 2.5, 7)
        for sgn in (-1, 1):
            S.lights.append(Light((X + sgn * (wd - 0.2), 0.68, z0 - 0.06), c, B=B, r_m=U(rng, 0.08, 0.12),
                                  glow=glow, glow_r=gr, halo=0.01, halo_r=25, ztol=0.3))
        if Z < 90:
            I = I_head if I_head else U(rng, 700, 2000)
            S.lights.append(Light((X, 0.68, z0 - 0.3), c, I=2 * I, mode='dir', axis=(0, -0.07, -1), k=18,
                                  spill=0.0, full=True))
    else:
        B = lights_B if lights_B else LU(rng, 5, 200)
        c = col(1.0, 0.05, 0.03)
        for sgn in (-1, 1):
            S.lights.append(Light((X + sgn * (wd - 0.15), 0.85, z1 + 0.06 - L_ - 0.0), c, B=B,
                                  r_m=U(rng, 0.06, 0.1), glow=LU(rng, 0.01, 0.06), glow_r=U(rng, 3, 8),
                                  ztol=0.3, spikes=False))
        if Z < 120 and chance(rng, 0.7):
            S.lights.append(Light((X, 0.68, z1 + 0.3), col(1.0, 0.95, 0.85), I=U(rng, 1000, 3000), mode='dir',
                                  axis=(0, -0.06, 1), k=18, spill=0.0, full=True, reflect=False))


# ----------------------------------------------------------------------------- finishing
def aniso_blur(img, sx, sy):
    k = 4 if sy > 10 else 1
    small = cv2.resize(img, (W, H // k), interpolation=cv2.INTER_AREA) if k > 1 else img
    small = cv2.GaussianBlur(small, (0, 0), sigmaX=sx, sigmaY=max(sy / k, 0.5))
    if k > 1:
        small = cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)
    return small


def reflections(S, src):
    """Mirror every non-ground surface (and sky) through the ground plane, blur vertically."""
    cam = S.cam
    if S.wet.max() <= 0:
        return None
    m = S.K != K_GROUND
    iy, ix = np.nonzero(m)
    Zs = S.Z[iy, ix]
    fin = np.isfinite(Zs)
    yd = np.where(fin, cam.yh + cam.f * (cam.hc + S.Y[iy, ix]) / np.where(fin, Zs, 1.0), 2 * cam.yh - (iy + 0.5))
    yi = np.floor(yd).astype(np.int64)
    ok = (yi >= 0) & (yi < H)
    flat = yi[ok] * W + ix[ok]
    vals = src[iy[ok], ix[ok]]
    acc = np.zeros((H * W, 3), F)
    for c in range(3):
        acc[:, c] = np.bincount(flat, weights=vals[:, c], minlength=H * W)
    cnt = np.bincount(flat, minlength=H * W).astype(F).reshape(H, W)
    acc = acc.reshape(H, W, 3)
    sx, sy = S.refl_sx, S.refl_sy
    ab = aniso_blur(acc, sx, sy)
    cb = aniso_blur(cnt, sx, sy)
    surf = ab / np.maximum(cb, 1e-4)[..., None] * np.clip(cb / 0.25, 0, 1)[..., None]
    pts = aniso_blur(S.refl_pts, sx * 0.8, sy * 0.8)
    R = surf + pts
    if S.ripple > 0:
        rp = fbm(S.rng, H // 2, W // 12, 3, 3)
        rp = cv2.resize(rp, (W, H), interpolation=cv2.INTER_LINEAR)
        R *= np.clip(1 + S.ripple * rp, 0.05, 2.5)[..., None]
    return R * S.wet[..., None]


def finish(S, post_light=None):
    """Shade the G-buffer, add emitters, reflections and lens effects -> HxWx3 float32."""
    E = light_pass(S)
    if S.amb_fill is not None:
        E += S.amb_fill
    img = S.L + S.A * E
    # neon glow + light spill
    if S.emit.max() > 0:
        small = cv2.resize(S.emit, (W // 4, H // 4), interpolation=cv2.INTER_AREA)
        wide = cv2.resize(cv2.GaussianBlur(small, (0, 0), 6), (W, H), interpolation=cv2.INTER_LINEAR)
        nglow = cv2.GaussianBlur(S.emit, (0, 0), U(S.rng, 1.5, 3.5))
        S.emit_total = S.emit + U(S.rng, 0.15, 0.5) * nglow + U(S.rng, 0.05, 0.2) * wide
    else:
        S.emit_total = S.emit
    if S.trail.max() > 0:
        S.emit_total = S.emit_total + S.trail + 0.15 * cv2.GaussianBlur(S.trail, (0, 0), 1.5)
    src = img + S.emit_total
    # mirrored point lights for the reflection layer
    if S.wet.max() > 0:
        for Lt in S.lights:
            if Lt.B > 0 and Lt.reflect:
                draw_light(S, S.refl_pts, Lt, mirror=True)
    R = reflections(S, src)
    img = src
    if R is not None:
        img = img + R
    for Lt in S.lights:
        if Lt.B > 0:
            draw_light(S, img, Lt)
    if post_light is not None:
        post_light(S, img)
    if S.haze > 0:
        small = cv2.resize(img, (W // 4, H // 4), interpolation=cv2.INTER_AREA)
        small = cv2.GaussianBlur(small, (0, 0), 8)
        img = img + S.haze * cv2.resize(small, (W, H), interpolation=cv2.INTER_LINEAR)
    img = np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(img, 0.0, 1e5).astype(F)


def setup_post(S, rng):
    if chance(rng, 0.35):
        S.spikes = dict(n=pick(rng, [4, 6, 8]), ang=U(rng, 0, math.pi), amp=LU(rng, 0.002, 0.01),
                        len=U(rng, 0.7, 1.6), thr=LU(rng, 2000, 8000))
    S.haze = LU(rng, 0.0003, 0.004) if chance(rng, 0.7) else 0.0


# ----------------------------------------------------------------------------- outdoor scenes
def street_ground_mat(P):
    def mat(S, X, Z, dX, dZ, sy, sx):
        n = X.size
        rel = X - P['Xc']
        ar = np.abs(rel)
        Rw, Sw = P['Rw'], P['Sw']
        tA, tB = S.texA[sy, sx], S.texB[sy, sx]
        att = 1.0 / (1.0 + dX * 40)
        road = ar < Rw
        side = (ar >= Rw) & (ar < Rw + Sw)
        out = ~(road | side)
        alb = np.empty((n, 3), F)
        ra = P['road_alb'] * np.clip(1 + 0.15 * tA + 0.35 * tB * att, 0.3, 2)[:, None]
        # markings
        mk = np.zeros(n, F)
        if P['two_way']:
            cx = interval_cov(rel, dX, -0.08, 0.08)
            mk = np.maximum(mk, cx * (box_cov(Z / 9.0, dZ / 9.0, 0, 0.4) if P['dash_c'] else 1.0))
        for lc in P['lane_lines']:
            mk = np.maximum(mk, interval_cov(rel, dX, lc - 0.06, lc + 0.06) * box_cov(Z / 12.0, dZ / 12.0, 0.2, 0.3))
        for s in (-1, 1):
            e = s * (Rw - 0.35)
            mk = np.maximum(mk, interval_cov(rel, dX, e - 0.07, e + 0.07))
        wear = np.clip(0.8 + 0.4 * tB, 0.3, 1.2) * P['mark_wear']
        mk *= wear
        ra = ra * (1 - mk[:, None]) + P['mark_col'][None, :] * mk[:, None]
        if P['xwalk'] is not None:   # white zebra crossing
            z0 = P['xwalk']
            xw = interval_cov(Z, dZ, z0, z0 + 4) * box_cov(rel / 1.1, dX / 1.1, 0, 0.5) * (ar < Rw - 0.5) * wear
            ra = ra * (1 - xw[:, None]) + col(0.5, 0.5, 0.48)[None, :] * xw[:, None]
        sa = P['side_alb'] * np.clip(1 + 0.12 * tA + 0.2 * tB * att, 0.3, 2)[:, None]
        j = np.maximum(box_cov(Z / P['tile'], dZ / P['tile'], 0, 0.03),
                       box_cov(rel / P['tile'], dX / P['tile'], 0, 0.03))
        sa *= (1 - 0.4 * j)[:, None]
        curb = interval_cov(ar, dX, Rw, Rw + 0.18)
        sa = sa * (1 - curb[:, None]) + 0.28 * curb[:, None]
        ga = P['out_alb'] * np.clip(1 + 0.3 * tA + 0.4 * tB * att, 0.2, 2.5)[:, None]
        alb[road] = ra[road]
        alb[side] = sa[side]
        alb[out] = ga[out]
        L = alb * P['amb']
        puddle = 0.3 + 0.7 * smoothstep(-0.4, 0.7, world_noise(S, X, Z, dX, dZ, P['pscale']))
        fres = 1 + 0.8 * np.exp(-(sy - S.cam.yh) / 80.0)
        wet = np.where(road, 1.0, np.where(side, 0.45, 0.0)) * P['wet'] * puddle * fres
        return L, alb, np.clip(wet, 0, 0.35).astype(F)
    return mat


def facade_row(S, side, Xface, z_start, z_end, downtown, rng, neon_p=0.3, depth=20.0):
    """Row of box buildings along the street (side=-1 left, +1 right). Returns list of segments."""
    segs = []
    z = z_start
    while z < z_end:
        wlen = U(rng, 8, 35)
        if chance(rng, 0.12) and z > 5:
            z += U(rng, 3, 10)
            continue
        Hb = LU(rng, 12, 90) if downtown else LU(rng, 6, 24)
        setback = U(rng, 0, 1.8) if chance(rng, 0.3) else 0.0
        xf = Xface + side * setback
        mat = Facade(rng, downtown=downtown)
        if side < 0:
            bmin, bmax = (xf - depth, 0, z), (xf, Hb, z + wlen)
        else:
            bmin, bmax = (xf, 0, z), (xf + depth, Hb, z + wlen)
        paint_box(S, bmin, bmax, mat)
        segs.append((z, z + wlen, xf, Hb, mat))
        z += wlen
    return segs


def skyline(S, rng, zmin, zmax, n, xspan, hmin=15, hmax=220, cluster=0.0, base_y=0.0, sort=True):
    items = []
    for _ in range(n):
        Zb = LU(rng, zmin, zmax)
        X = rng.normal(cluster, xspan * 0.5) if chance(rng, 0.6) else U(rng, -xspan, xspan)
        wb = U(rng, 12, 60)
        Hb = LU(rng, hmin, hmax) * (1.6 if abs(X - cluster) < xspan * 0.2 else 1.0)
        items.append((Zb, X, wb, Hb))
    items.sort()
    for Zb, X, wb, Hb in items:
        mat = Facade(rng, style=pick(rng, ['office', 'glass', 'home', 'office', 'brick']), downtown=True)
        paint_box(S, (X - wb / 2, base_y, Zb), (X + wb / 2, base_y + Hb, Zb + U(rng, 15, 50)), mat)
        if Hb > 80 and chance(rng, 0.7):
            S.lights.append(Light((X, base_y + Hb + 1.0, Zb - 0.5), col(1.0, 0.05, 0.03), B=LU(rng, 5, 80),
                                  r_px=U(rng, 1.0, 1.8), glow=LU(rng, 0.02, 0.1), glow_r=U(rng, 2, 5),
                                  ztol=3.0, spikes=False))
    return items


def hills(S, rng, Z, hmax, colr_amb, lights_n=0):
    """Distant terrain silhouette (1D noise profile) with a few house lights."""
    cam = S.cam
    prof = fbm(rng, 1, W + 64, U(rng, 80, 250), 4)[0, :W]
    hpx = (prof - prof.min()) / max(np.ptp(prof), 1e-3)
    hm = hmax * (0.3 + 0.7 * hpx)
    ytop = cam.yh + cam.f * (cam.hc - hm) / Z
    yy = np.arange(H)[:, None] + 0.5
    m = (yy >= ytop[None, :]) & (S.Z > Z)
    iy, ix = np.nonzero(m)
    n = iy.size
    if n == 0:
        return
    a = np.tile(col(0.05, 0.06, 0.05), (n, 1))
    L = a * colr_amb * np.clip(1 + 0.3 * S.texA[iy, ix], 0.3, 2)[:, None]
    S.write(iy, ix, np.full(n, Z, F), 4, K_BUILD, L, a * 0)
    for _ in range(lights_n):
        x = int(rng.integers(0, W))
        y = int(U(rng, ytop[x] + 2, min(H - 1, cam.yh + 10)))
        if 0 <= y < H and S.Z[y, x] >= Z - 1:
            S.emit[y, x] += pick(rng, list(STREET.values())) * LU(rng, 0.5, 15)


def build_avenue(rng):
    f = U(rng, 520, 900)
    hc = U(rng, 4, 9) if chance(rng, 0.2) else U(rng, 1.4, 2.2)
    cam = Cam(f, hc, W / 2 + U(rng, -150, 150), H * U(rng, 0.40, 0.56))
    S = Scene(rng, cam, 'avenue')
    downtown = chance(rng, 0.55)
    Rw = U(rng, 4, 9.5)
    Xc = U(rng, -0.7, 0.7) * Rw
    Sw = U(rng, 2.5, 6)
    nl = max(1, int(Rw / 3.3))
    P = dict(Xc=Xc, Rw=Rw, Sw=Sw, road_alb=col(0.10, 0.10, 0.095) * U(rng, 0.6, 1.3),
             side_alb=col(0.2, 0.19, 0.18) * U(rng, 0.7, 1.3), out_alb=col(0.05, 0.07, 0.035) * U(rng, 0.6, 1.4),
             mark_col=pick(rng, [col(0.5, 0.5, 0.48), col(0.55, 0.42, 0.1)]), mark_wear=U(rng, 0.5, 1.0),
             two_way=chance(rng, 0.8), dash_c=chance(rng, 0.6),
             lane_lines=[s * 3.3 * i for s in (-1, 1) for i in range(1, nl)],
             xwalk=U(rng, 10, 40) if chance(rng, 0.3) else None, tile=U(rng, 0.8, 2.0),
             amb=LU(rng, 0.05, 0.15), wet=U(rng, 0.05, 0.3) if chance(rng, 0.6) else 0.0, pscale=U(rng, 2, 8))
    S.refl_sx, S.refl_sy = U(rng, 1.2, 4), U(rng, 12, 80)
    paint_ground(S, street_ground_mat(P))
    sides = {}
    zend = U(rng, 150, 600)
    for s in (-1, 1):
        if chance(rng, 0.85):
            sides[s] = facade_row(S, s, Xc + s * (Rw + Sw), U(rng, -12, 2), zend, downtown, rng)
        else:
            sides[s] = None
    if chance(rng, 0.75 if downtown else 0.45):
        skyline(S, rng, max(zend, 300) + 100, max(zend, 300) + 1500, int(U(rng, 10, 40)), 700,
                cluster=U(rng, -200, 200))
    elif chance(rng, 0.5):
        hills(S, rng, 3000, U(rng, 40, 200), 0.05, int(U(rng, 0, 30)))
    # lamps
    key = pick(rng, list(STREET.keys()))
    B0 = LU(rng, 100, 1500) if key.startswith('sodium') else LU(rng, 200, 3000)
    pool = LU(rng, 0.05, 0.5)
    Hl0 = U(rng, 6, 10)
    glow0, gr0 = LU(rng, 0.005, 0.1), U(rng, 2, 7)
    halo0 = LU(rng, 0.003, 0.03) if chance(rng, 0.5) else 0.0
    k0, spill0 = U(rng, 1.5, 4), U(rng, 0.01, 0.04)
    arr = pick(rng, ['both', 'both', 'left', 'right', 'median', 'stagger'])
    spacing = U(rng, 18, 40)
    road_a = float(P['road_alb'].mean())
    z = U(rng, 8, 25)
    i = 0
    while z < min(zend + 100, 450):
        sl = []
        if arr in ('both', 'left') or (arr == 'stagger' and i % 2 == 0):
            sl.append(-1)
        if arr in ('both', 'right') or (arr == 'stagger' and i % 2 == 1):
            sl.append(1)
        for s in sl:
            c = STREET[key] if not chance(rng, 0.1) else pick(rng, list(STREET.values()))
            Hl = Hl0 * U(rng, 0.95, 1.05)
            I = pool * U(rng, 0.8, 1.2) * Hl * Hl / road_a
            add_street_lamp(S, Xc + s * (Rw + 0.4), z, Hl, -s * U(rng, 0.8, 2.5), c, B0 * U(rng, 0.7, 1.3), I,
                            k0, spill0, glow0 * U(rng, 0.7, 1.3), gr0, halo0, U(rng, 15, 50), U(rng, 0.1, 0.25))
        if arr == 'median':
            Hl = Hl0
            I = pool * Hl * Hl / road_a
            paint_box(S, (Xc - 0.08, 0, z - 0.08), (Xc + 0.08, Hl, z + 0.08), Plain(col(0.09, 0.09, 0.1), 0.02), K_FIXT)
            for s in (-1, 1):
                paint_box(S, (Xc + s * 1.7 - 0.3, Hl, z - 0.15), (Xc + s * 1.7 + 0.3, Hl + 0.12, z + 0.15),
                          Plain(col(0.09, 0.09, 0.1), 0.02), K_FIXT)
                S.lights.append(Light((Xc + s * 1.7, Hl - 0.03, z), STREET[key], I=I, mode='dir', k=k0, spill=spill0,
                                      excl=0.6, B=B0, r_m=0.15, glow=glow0, glow_r=gr0, halo=halo0))
        z += spacing * U(rng, 0.9, 1.1)
        i += 1
    # wall lanterns on facades
    for s, segs in sides.items():
        if segs and chance(rng, 0.3):
            c = pick(rng, [INDOOR['incandescent'], INDOOR['halogen'], STREET['led_warm']])
            for (z0, z1, xf, Hb, mat) in segs:
                if z1 < 4 or z0 > 150:
                    continue
                zz = U(rng, max(z0, 3) + 0.5, max(z1, 4) - 0.5) if z1 - max(z0, 3) > 1 else None
                if zz is None:
                    continue
                S.lights.append(Light((xf - s * 0.25, U(rng, 2.8, 4), zz), c, I=U(rng, 1, 4), mode='iso', excl=0.3,
                                      B=LU(rng, 20, 400), r_m=0.08, glow=LU(rng, 0.01, 0.08), glow_r=U(rng, 3, 8)))
    # trees along sidewalk
    if chance(rng, 0.5):
        for s in (-1, 1):
            if chance(rng, 0.7):
                z = U(rng, 4, 20)
                while z < 220:
                    paint_tree(S, Xc + s * (Rw + U(rng, 0.8, 1.6)), z, U(rng, 2, 3.5), U(rng, 3, 6), U(rng, 3, 6),
                               'deciduous', col(0.05, 0.08, 0.035) * U(rng, 0.7, 1.5), LU(rng, 0.03, 0.1))
                    z += U(rng, 8, 25)
    # traffic signals
    if chance(rng, 0.35):
        zt = U(rng, 20, 60)
        state = pick(rng, [0, 1, 2])
        for s in (-1, 1):
            xp = Xc + s * (Rw + 0.5)
            paint_box(S, (xp - 0.06, 0, zt - 0.06), (xp + 0.06, 3.6, zt + 0.06),
                      Plain(col(0.08, 0.08, 0.08), 0.02), K_FIXT)
            paint_box(S, (xp - 0.18, 3.0, zt + 0.05), (xp + 0.18, 4.1, zt + 0.3),
                      Plain(col(0.03, 0.03, 0.03), 0.02), K_FIXT)
            for j, c in enumerate([col(1.0, 0.08, 0.03), col(1.0, 0.55, 0.05), col(0.15, 1.0, 0.55)]):
                on = j == state
                S.lights.append(Light((xp, 3.9 - j * 0.33, zt), c, B=LU(rng, 30, 300) if on else 0.05,
                                      r_m=0.1, glow=LU(rng, 0.02, 0.1) if on else 0.0, glow_r=U(rng, 3, 8), ztol=0.2,
                                      spikes=on))
    # traffic
    rh = 1 if chance(rng, 0.7) else -1
    lanes = [(Xc + s * (1.65 + 3.3 * i), -s * rh) for s in (-1, 1) for i in range(nl)]
    trails = chance(rng, 0.35)
    if trails:
        for Xl, facing in lanes:
            for _ in range(int(rng.integers(1, 4))):
                off = U(rng, -0.4, 0.4)
                zs = np.linspace(LU(rng, 0.6, 6), U(rng, 150, 500), 160)
                lc = U(rng, 0, 1)
                xs = Xl + off + np.zeros_like(zs)
                if chance(rng, 0.2):   # lane change
                    xs = xs + 3.3 * np.sign(rng.standard_normal()) * smoothstep(lc * 200, lc * 200 + 30, zs)
                for sgn in (-1, 1):
                    if facing < 0:
                        c, v, y = col(1.0, 0.95, 0.85), LU(rng, 8, 60), 0.68
                    else:
                        c, v, y = col(1.0, 0.06, 0.03), LU(rng, 4, 30), 0.85
                    pts = np.stack([xs + sgn * 0.75, np.full_like(zs, y), zs], 1)
                    draw_polyline3d(S, pts, c, v, reflect=P['wet'] > 0)
    else:
        for Xl, facing in lanes:
            z = LU(rng, 6, 60)
            if abs(Xl) < 2.2 and facing < 0:   # oncoming traffic in the camera's own lane: keep distance
                z = max(z, U(rng, 25, 60))
            while z < 350 and chance(rng, 0.8):
                add_car(S, Xl + U(rng, -0.3, 0.3), z, facing)
                z += U(rng, 8, 40) + 0.2 * z * U(rng, 0.2, 1.5)
    if chance(rng, 0.5):
        for s in (-1, 1):
            z = U(rng, 4, 20)
            while z < 90 and chance(rng, 0.75):
                add_car(S, Xc + s * (Rw - 1.1), z, 1, headlights_on=False)
                z += U(rng, 5.5, 12)
    # neon signs
    if chance(rng, 0.65 if downtown else 0.35):
        cands = [(s, seg) for s, segs in sides.items() if segs for seg in segs if seg[1] > 6 and seg[0] < 120]
        for _ in range(int(rng.integers(2, 8))):
            if not cands:
                break
            s, (z0, z1, xf, Hb, mat) = pick(rng, cands)
            zz0 = max(z0, 5) + U(rng, 0.3, 2)
            if chance(rng, 0.55):
                ln = U(rng, 2, 6)
                if zz0 + ln > z1:
                    continue
                y0, hh = U(rng, 2.8, 4.5), U(rng, 0.5, 1.2)
                xo = xf - s * 0.05
                if s < 0:   # text reads far -> near on the left facade
                    corners = [(xo, y0 + hh, zz0 + ln), (xo, y0 + hh, zz0), (xo, y0, zz0), (xo, y0, zz0 + ln)]
                else:
                    corners = [(xo, y0 + hh, zz0), (xo, y0 + hh, zz0 + ln), (xo, y0, zz0 + ln), (xo, y0, zz0)]
                add_neon_sign(S, corners)
            else:  # vertical blade sign facing the camera
                out_ = U(rng, 0.7, 1.2)
                y0, hh = U(rng, 3, 5), U(rng, 2.5, 6)
                xa, xb = sorted([xf, xf - s * out_])
                paint_box(S, (xa, y0, zz0), (xb, y0 + hh, zz0 + 0.2), Plain(col(0.06, 0.06, 0.07), 0.05), K_OBJ)
                corners = [(xa + 0.05, y0 + hh - 0.1, zz0 - 0.02), (xb - 0.05, y0 + hh - 0.1, zz0 - 0.02),
                           (xb - 0.05, y0 + 0.1, zz0 - 0.02), (xa + 0.05, y0 + 0.1, zz0 - 0.02)]
                add_neon_sign(S, corners, vertical=True)
    paint_sky(S, sky_params(rng, city=True))
    setup_post(S, rng)
    return finish(S)


def build_across(rng):
    f = U(rng, 480, 800)
    hc = U(rng, 1.5, 2.6)
    cam = Cam(f, hc, W / 2 + U(rng, -100, 100), H * U(rng, 0.56, 0.76))
    S = Scene(rng, cam, 'across')
    Zb = U(rng, 18, 40)
    nl = int(rng.integers(1, 3))
    Sw = U(rng, 2.5, 5)
    z_road1 = Zb - Sw
    z_road0 = z_road1 - nl * 2 * 3.3
    downtown = chance(rng, 0.5)
    amb = LU(rng, 0.05, 0.15)
    road_alb = col(0.1, 0.1, 0.095) * U(rng, 0.6, 1.3)
    side_alb = col(0.2, 0.19, 0.18) * U(rng, 0.7, 1.3)
    wetk = U(rng, 0.05, 0.3) if chance(rng, 0.5) else 0.0
    tile = U(rng, 0.8, 2.0)
    pscale = U(rng, 2, 8)
    S.refl_sx, S.refl_sy = U(rng, 1.2, 4), U(rng, 12, 70)

    def gmat(S, X, Z, dX, dZ, sy, sx):
        tA, tB = S.texA[sy, sx], S.texB[sy, sx]
        att = 1.0 / (1.0 + dX * 40)
        road = (Z >= z_road0) & (Z < z_road1)
        ra = road_alb * np.clip(1 + 0.15 * tA + 0.35 * tB * att, 0.3, 2)[:, None]
        zmid = (z_road0 + z_road1) / 2
        mk = interval_cov(Z, dZ, zmid - 0.07, zmid + 0.07) * box_cov(X / 9.0, dX / 9.0, 0, 0.4)
        for s in (-1, 1):
            e = zmid + s * (nl * 3.3 - 0.3)
            mk = np.maximum(mk, interval_cov(Z, dZ, e - 0.07, e + 0.07))
        ra = ra * (1 - 0.8 * mk[:, None]) + 0.45 * 0.8 * mk[:, None]
        sa = side_alb * np.clip(1 + 0.12 * tA + 0.2 * tB * att, 0.3, 2)[:, None]
        j = np.maximum(box_cov(Z / tile, dZ / tile, 0, 0.03), box_cov(X / tile, dX / tile, 0, 0.03))
        sa *= (1 - 0.4 * j)[:, None]
        for zc in (z_road0, z_road1):
            cb = interval_cov(Z, dZ, zc - 0.18, zc)
            sa = sa * (1 - cb[:, None]) + 0.28 * cb[:, None]
        alb = np.where(road[:, None], ra, sa)
        puddle = 0.3 + 0.7 * smoothstep(-0.4, 0.7, world_noise(S, X, Z, dX, dZ, pscale))
        fres = 1 + 0.8 * np.exp(-(sy - cam.yh) / 80.0)
        wet = np.where(road, 1.0, 0.45) * wetk * puddle * fres
        return alb * amb, alb, np.clip(wet, 0, 0.35).astype(F)
    paint_ground(S, gmat)
    # facade row (frontal)
    span = Zb * (W / 2 + abs(cam.xv - W / 2)) / f + 15
    x = -span
    facs = []
    while x < span:
        wb = U(rng, 6, 26)
        if chance(rng, 0.1):
            x += U(rng, 3, 8)
            continue
        Hb = LU(rng, 10, 70) if downtown else LU(rng, 6, 20)
        zf = Zb + (U(rng, 0, 3) if chance(rng, 0.3) else 0)
        mat = Facade(rng, downtown=downtown, shops=chance(rng, 0.6))
        paint_box(S, (x, 0, zf), (x + wb, Hb, zf + 20), mat)
        facs.append((x, x + wb, zf, Hb, mat))
        x += wb
    # second row behind
    for _ in range(int(rng.integers(4, 14))):
        xb = U(rng, -span * 2, span * 2)
        zb2 = Zb + U(rng, 30, 150)
        paint_box(S, (xb, 0, zb2), (xb + U(rng, 10, 40), LU(rng, 15, 120), zb2 + 20), Facade(rng, downtown=True))
    # lamps on the far sidewalk
    key = pick(rng, list(STREET.keys()))
    B0 = LU(rng, 100, 1500) if key.startswith('sodium') else LU(rng, 200, 3000)
    pool = LU(rng, 0.05, 0.5)
    glow0, gr0 = LU(rng, 0.005, 0.1), U(rng, 2, 7)
    halo0 = LU(rng, 0.003, 0.03) if chance(rng, 0.5) else 0.0
    spacing = U(rng, 15, 35)
    Hl = U(rng, 5, 9)
    xl = -span + U(rng, 0, spacing)
    pole = Plain(col(0.09, 0.09, 0.1), 0.02, 0.1)
    while xl < span:
        zl = Zb - U(rng, 0.6, 1.2)
        c = STREET[key] if not chance(rng, 0.1) else pick(rng, list(STREET.values()))
        I = pool * Hl * Hl / float(side_alb.mean())
        paint_box(S, (xl - 0.07, 0, zl - 0.07), (xl + 0.07, Hl + 0.1, zl + 0.07), pole, K_FIXT)
        arm = U(rng, 0.8, 2.0)
        paint_box(S, (xl - 0.04, Hl + 0.02, zl - arm), (xl + 0.04, Hl + 0.1, zl), pole, K_FIXT)
        paint_box(S, (xl - 0.15, Hl + 0.03, zl - arm - 0.35), (xl + 0.15, Hl + 0.16, zl - arm + 0.35), pole, K_FIXT)
        S.lights.append(Light((xl, Hl - 0.03, zl - arm), c, I=I, mode='dir', k=U(rng, 1.5, 3.5), spill=0.03,
                              excl=0.6, B=B0 * U(rng, 0.7, 1.3), r_m=U(rng, 0.1, 0.25),
                              glow=glow0 * U(rng, 0.7, 1.3), glow_r=gr0, halo=halo0, halo_r=U(rng, 15, 50)))
        xl += spacing * U(rng, 0.85, 1.15)
    if chance(rng, 0.4):
        for _ in range(int(rng.integers(2, 6))):
            paint_tree(S, U(rng, -span, span), Zb - U(rng, 1.2, 2.2), U(rng, 2, 3), U(rng, 3, 6), U(rng, 3, 5),
                       'deciduous', col(0.05, 0.08, 0.035) * U(rng, 0.7, 1.5), LU(rng, 0.03, 0.1))
    # neon on shop floors
    if chance(rng, 0.7):
        for _ in range(int(rng.integers(1, 7))):
            x0, x1, zf, Hb, mat = pick(rng, facs)
            ln = min(U(rng, 2, 6), x1 - x0 - 0.5)
            if ln < 1:
                continue
            xa = U(rng, x0 + 0.2, x1 - ln - 0.2) if x1 - ln - 0.2 > x0 + 0.2 else x0 + 0.2
            y0 = U(rng, 2.8, 4.5) if mat.gf == 0 else mat.gf - U(rng, 0.2, 0.9)
            hh = U(rng, 0.5, 1.2)
            zs = zf - 0.05
            add_neon_sign(S, [(xa, y0 + hh, zs), (xa + ln, y0 + hh, zs), (xa + ln, y0, zs), (xa, y0, zs)])
    # traffic
    lanes = [z_road0 + 3.3 * (i + 0.5) for i in range(2 * nl)]
    if chance(rng, 0.7):
        for li, zl in enumerate(lanes):
            dirn = 1 if li < nl else -1
            for _ in range(int(rng.integers(1, 3))):
                xs = np.linspace(-span * 1.5, span * 1.5, 120)
                zz = zl + U(rng, -0.6, 0.6) + 0.15 * np.sin(xs / U(rng, 8, 30))
                bus = chance(rng, 0.15)
                for (yv, c, v) in [(U(rng, 0.6, 0.95), col(1.0, 0.06, 0.03), LU(rng, 3, 30)),
                                   (U(rng, 0.5, 0.75), col(1.0, 0.95, 0.85), LU(rng, 5, 60))]:
                    if bus:
                        yv += U(rng, 1.5, 2.3)
                    zside = zz - (0.9 if dirn > 0 else -0.9) * 0 - 0.9
                    gapk = int(rng.integers(5, 40))
                    pts = np.stack([xs, np.full_like(xs, yv), zside], 1)
                    draw_polyline3d(S, pts, c, v, width_m=0.06, maxpx=2, reflect=wetk > 0,
                                    gap_fn=(lambda i, g=gapk: (i % g) == 0) if chance(rng, 0.4) else None)
    else:
        for _ in range(int(rng.integers(1, 6))):
            zl = pick(rng, lanes)
            xc = U(rng, -span * 0.8, span * 0.8)
            body = Plain(pick(rng, [col(0.5, 0.5, 0.5), col(0.05, 0.05, 0.05), col(0.4, 0.05, 0.04)]), 0.03, 0.1)
            L_ = U(rng, 4, 4.8)
            paint_box(S, (xc, 0.28, zl - 0.9), (xc + L_, 0.95, zl + 0.9), body, K_OBJ)
            paint_box(S, (xc + 1.0, 0.95, zl - 0.8), (xc + L_ - 1.0, 1.45, zl + 0.8),
                      Plain(col(0.02, 0.02, 0.025), 0.03), K_OBJ)
            head_right = chance(rng, 0.5)
            xh, xt = (xc + L_ + 0.05, xc - 0.05) if head_right else (xc - 0.05, xc + L_ + 0.05)
            S.lights.append(Light((xh, 0.68, zl - 0.75), col(1.0, 0.96, 0.9), B=LU(rng, 50, 5000), r_m=0.1,
                                  glow=LU(rng, 0.02, 0.1), glow_r=U(rng, 2.5, 8), ztol=0.5))
            S.lights.append(Light((xt, 0.85, zl - 0.75), col(1.0, 0.05, 0.03), B=LU(rng, 5, 200), r_m=0.08,
                                  glow=LU(rng, 0.01, 0.06), glow_r=U(rng, 3, 7), ztol=0.5, spikes=False))
    paint_sky(S, sky_params(rng, city=True))
    setup_post(S, rng)
    return finish(S)


def build_skyline(rng):
    f = U(rng, 600, 1100)
    hc = LU(rng, 3, 40)
    cam = Cam(f, hc, W / 2 + U(rng, -120, 120), H * U(rng, 0.5, 0.72))
    S = Scene(rng, cam, 'skyline')
    Zs = LU(rng, 150, 700)
    wet = U(rng, 0.12, 0.3)
    water_alb = col(0.02, 0.025, 0.03)
    S.refl_sx, S.refl_sy = U(rng, 1.0, 3.0), U(rng, 25, 110)
    S.ripple = U(rng, 0.4, 1.0)
    wamb = LU(rng, 0.05, 0.2)

    def wmat(S, X, Z, dX, dZ, sy, sx):
        water = Z < Zs
        alb = np.where(water[:, None], water_alb[None, :], col(0.08, 0.08, 0.07)[None, :])
        L = alb * wamb * np.clip(1 + 0.2 * S.texA[sy, sx], 0.3, 2)[:, None]
        fres = 1 + 0.8 * np.exp(-(sy - cam.yh) / 60.0)
        return L, alb, np.where(water, np.clip(wet * fres, 0, 0.35), 0.0).astype(F)
    paint_ground(S, wmat)
    span = Zs * (W / 2 + 150) / f
    # embankment wall + promenade lamps
    hw = U(rng, 1.5, 5)
    paint_box(S, (-span * 3, 0, Zs), (span * 3, hw, Zs + 15), Plain(col(0.15, 0.14, 0.12), LU(rng, 0.02, 0.08), 0.3))
    key = pick(rng, list(STREET.keys()))
    if chance(rng, 0.8):
        sp = U(rng, 12, 35)
        x = -span * 1.5
        Bp = LU(rng, 100, 2000)
        g0, gr = LU(rng, 0.01, 0.1), U(rng, 3, 10)
        while x < span * 1.5:
            S.lights.append(Light((x, hw + U(rng, 3.5, 6), Zs + 2), STREET[key], I=U(rng, 20, 80), mode='dir',
                                  k=2, spill=0.05, excl=0.5, B=Bp * U(rng, 0.8, 1.2), r_m=0.25, glow=g0,
                                  glow_r=gr, ztol=3.0))
            x += sp
    if chance(rng, 0.5):
        for _ in range(int(rng.integers(3, 15))):
            paint_tree(S, U(rng, -span * 1.2, span * 1.2), Zs + U(rng, 3, 12), U(rng, 1, 3), U(rng, 4, 9),
                       U(rng, 4, 9), pick(rng, ['deciduous', 'conifer']), col(0.04, 0.06, 0.03), 0.05, yb_m=hw)
    skyline(S, rng, Zs + 20, Zs + LU(rng, 600, 2500), int(U(rng, 30, 110)), span * 2.5, hmin=12, hmax=200,
            cluster=U(rng, -span * 0.5, span * 0.5), base_y=hw)
    if chance(rng, 0.35):
        hills(S, rng, Zs + 4000, U(rng, 150, 500), 0.05, int(U(rng, 5, 60)))
    # bridge with lamp row
    if chance(rng, 0.45):
        zbr = Zs * U(rng, 0.35, 0.8)
        yd = U(rng, 8, 25)
        x0b, x1b = -span * U(rng, 1.2, 3), span * U(rng, 0.2, 3)
        deck = Plain(col(0.12, 0.12, 0.12), 0.03, 0.2)
        paint_box(S, (x0b, yd - 1.5, zbr), (x1b, yd, zbr + 15), deck)
        px = x0b
        while px < x1b:
            paint_box(S, (px - 1.5, 0, zbr + 3), (px + 1.5, yd - 1.5, zbr + 10), deck)
            px += U(rng, 60, 150)
        bk = pick(rng, list(STREET.keys()))
        sp = U(rng, 20, 40)
        px = x0b + sp / 2
        Bb = LU(rng, 100, 2000)
        while px < x1b:
            S.lights.append(Light((px, yd + U(rng, 5, 9), zbr), STREET[bk], I=U(rng, 30, 100), mode='dir', k=2,
                                  spill=0.05, excl=0.5, B=Bb, r_m=0.25, glow=LU(rng, 0.01, 0.08),
                                  glow_r=U(rng, 3, 8), ztol=3))
            px += sp
        if chance(rng, 0.5):  # string lights along catenary cables
            xs = np.linspace(x0b, x1b, int(U(rng, 40, 120)))
            yc = yd + 30 - 25 * np.cos((xs - xs.mean()) / (x1b - x0b) * 3.5)
            cc = pick(rng, [col(1.0, 0.9, 0.7), col(0.8, 0.9, 1.0), NEON['blue'], NEON['white']])
            bb = LU(rng, 5, 40)
            for xx, yy in zip(xs, yc):
                S.lights.append(Light((xx, yy, zbr + 7), cc, B=bb, r_px=1.0, glow=0.05, glow_r=2, ztol=5,
                                      spikes=False))
    p = sky_params(rng, city=True)
    p['moon'] = chance(rng, 0.5)
    paint_sky(S, p)
    setup_post(S, rng)
    return finish(S)


def build_park(rng):
    f = U(rng, 450, 800)
    hc = U(rng, 1.5, 1.8)
    cam = Cam(f, hc, W / 2 + U(rng, -120, 120), H * U(rng, 0.45, 0.62))
    S = Scene(rng, cam, 'park')
    a_, b_, ph = U(rng, 1, 6), U(rng, 15, 60), U(rng, 0, 6.28)
    pw = U(rng, 1.0, 2.5)
    x_off = 0.0

    U0 = U(rng, -0.5, 0.5) * pw

    def pc(Z):
        return x_off + a_ * np.sin(Z / b_ + ph) - a_ * math.sin(ph) + U0
    wet = U(rng, 0.05, 0.25) if chance(rng, 0.3) else 0.0
    amb = LU(rng, 0.04, 0.15)
    gal = col(0.04, 0.065, 0.03) * U(rng, 0.7, 1.4)
    pal_ = col(0.2, 0.18, 0.15) * U(rng, 0.7, 1.3)
    S.refl_sx, S.refl_sy = U(rng, 1.5, 4), U(rng, 10, 40)

    def gmat(S, X, Z, dX, dZ, sy, sx):
        tA, tB = S.texA[sy, sx], S.texB[sy, sx]
        att = 1.0 / (1.0 + dX * 40)
        d = np.abs(X - pc(Z))
        path = interval_cov(d, dX, -1, pw)
        ga = gal * np.clip(1 + 0.35 * tA + 0.5 * tB * att, 0.2, 2.5)[:, None]
        pa = pal_ * np.clip(1 + 0.15 * tA + 0.4 * tB * att, 0.3, 2)[:, None]
        alb = ga * (1 - path[:, None]) + pa * path[:, None]
        puddle = smoothstep(0.2, 0.9, world_noise(S, X, Z, dX, dZ, 3.0))
        return alb * amb, alb, (path * puddle * wet).astype(F)
    paint_ground(S, gmat)
    hills(S, rng, U(rng, 800, 3000), U(rng, 20, 150), 0.06, int(U(rng, 0, 40)))
    # far tree line
    if chance(rng, 0.6):
        zt = U(rng, 150, 400)
        for xx in np.linspace(-zt, zt, int(U(rng, 20, 50))):
            paint_tree(S, xx + U(rng, -5, 5), zt + U(rng, -20, 20), U(rng, 1, 3), U(rng, 8, 16), U(rng, 8, 18),
                       pick(rng, ['deciduous', 'conifer']), col(0.03, 0.045, 0.025), 0.04)
    # houses
    if chance(rng, 0.5):
        for _ in range(int(rng.integers(1, 5))):
            zh = U(rng, 50, 220)
            xh = U(rng, -zh * 0.6, zh * 0.6)
            if abs(xh - pc(zh)) < 8:
                continue
            paint_box(S, (xh, 0, zh), (xh + U(rng, 8, 16), U(rng, 5, 9), zh + 10),
                      Facade(rng, style='home', lit_p=U(rng, 0.1, 0.5), shops=False))
    # lamps along the path
    key = pick(rng, ['sodium_hp', 'led_warm', 'led_neutral', 'mercury', 'metal_halide', 'led_cool'])
    B0 = LU(rng, 50, 1500)
    pool = U(rng, 0.05, 0.3)
    Hl = U(rng, 3, 4.5)
    glow0 = LU(rng, 0.005, 0.05)
    gr0 = U(rng, 2, 6)
    halo0 = LU(rng, 0.005, 0.04) if chance(rng, 0.6) else 0.0
    z = U(rng, 5, 15)
    sp = U(rng, 15, 30)
    side = pick(rng, [-1, 1])
    lamp_pos = []
    while z < 160:
        xl = float(pc(z)) + side * (pw + 0.6)
        if chance(rng, 0.3):
            side = -side
        I = pool * Hl * Hl / float(pal_.mean())
        add_street_lamp(S, xl, z, Hl, 0, STREET[key], B0 * U(rng, 0.7, 1.3), I, 0, 1, glow0, gr0, halo0,
                        U(rng, 15, 50), U(rng, 0.12, 0.22), style='post')
        lamp_pos.append((xl, z))
        z += sp * U(rng, 0.8, 1.2)
    # benches
    for (xl, zl) in lamp_pos[:4]:
        if chance(rng, 0.5):
            paint_box(S, (xl + 0.4, 0.4, zl + 0.6), (xl + 0.9, 0.48, zl + 2.3),
                      Plain(col(0.2, 0.12, 0.06), 0.03), K_OBJ)
            paint_box(S, (xl + 0.85, 0.48, zl + 0.6), (xl + 0.92, 0.9, zl + 2.3),
                      Plain(col(0.2, 0.12, 0.06), 0.03), K_OBJ)
    # trees
    for _ in range(int(U(rng, 12, 45))):
        zt = LU(rng, 4, 150)
        xt = U(rng, -zt * 0.8 - 5, zt * 0.8 + 5)
        if abs(xt - pc(zt)) < pw + 2:
            continue
        cwid = U(rng, 3, 9)
        paint_tree(S, xt, zt, U(rng, 1.5, 4), cwid, cwid * U(rng, 0.8, 1.6),
                   pick(rng, ['deciduous', 'deciduous', 'conifer']),
                   col(0.04, 0.07, 0.03) * U(rng, 0.6, 1.5), amb * U(rng, 0.3, 0.8))
    if chance(rng, 0.4):
        zt = U(rng, 2.5, 5)
        paint_tree(S, pick(rng, [-1, 1]) * U(rng, 2, 4), zt, U(rng, 2, 4), U(rng, 5, 9), U(rng, 4, 8), 'deciduous',
                   col(0.03, 0.05, 0.02), amb * 0.5)
    p = sky_params(rng, city=chance(rng, 0.3))
    paint_sky(S, p)
    setup_post(S, rng)
    if chance(rng, 0.3):   # fog: brighter, wider glows
        for Lt in S.lights:
            Lt.halo = max(Lt.halo, LU(rng, 0.005, 0.015))
            Lt.halo_r = U(rng, 25, 60)
        S.haze = max(S.haze, LU(rng, 0.002, 0.006))
    return finish(S)


# ----------------------------------------------------------------------------- interior
def build_interior(rng):
    f = U(rng, 380, 600)
    hc = U(rng, 1.1, 1.7)
    cam = Cam(f, hc, W / 2 + U(rng, -120, 120), H * U(rng, 0.42, 0.6))
    S = Scene(rng, cam, 'interior')
    wl, wr = U(rng, 1.6, 3.5), U(rng, 1.6, 3.5)
    Hr, D = U(rng, 2.4, 3.2), U(rng, 4.0, 8.0)
    wall_c = pick(rng, [col(0.75, 0.7, 0.62), col(0.8, 0.8, 0.78), col(0.5, 0.55, 0.6), col(0.55, 0.62, 0.5),
                        col(0.7, 0.55, 0.45), col(0.35, 0.38, 0.5)]) * U(rng, 0.6, 1.0)
    floor_kind = pick(rng, ['wood', 'wood', 'tile', 'carpet'])
    floor_c = {'wood': col(0.35, 0.22, 0.12), 'tile': col(0.45, 0.44, 0.42), 'carpet': col(0.25, 0.22, 0.2)}[floor_kind]
    floor_c = floor_c * U(rng, 0.5, 1.2)
    ceil_c = col(0.78, 0.77, 0.75)
    stripes = chance(rng, 0.25)
    # window
    wface = pick(rng, [4, 4, 2, 3])
    if wface == 4:
        wu0 = U(rng, -wl + 0.3, wr - 2.0)
        wu1 = min(wu0 + U(rng, 1.0, 2.4), wr - 0.2)
    else:
        wu0 = U(rng, 1.0, max(1.2, D - 2.5))
        wu1 = min(wu0 + U(rng, 1.0, 2.2), D - 0.3)
    wv0 = U(rng, 0.6, 1.0)
    wv1 = min(wv0 + U(rng, 1.2, 1.8), Hr - 0.2)
    curtain_c = pick(rng, [col(0.6, 0.1, 0.08), col(0.7, 0.65, 0.55), col(0.15, 0.2, 0.4), col(0.3, 0.35, 0.25)])
    curtains = chance(rng, 0.6)
    mull = chance(rng, 0.7)
    frame_c = pick(rng, [col(0.7, 0.7, 0.68), col(0.15, 0.1, 0.07)])
    outP = sky_params(rng, city=True)
    outP['clouds'] = 0.0
    az = np.linspace(-1.6, 1.6, 800)
    prof = fbm(rng, 1, 800, U(rng, 20, 80), 3)[0]
    prof = np.round(np.clip(0.02 + 0.05 * prof, -0.02, 0.18) * 60) / 60  # blocky skyline
    osalt = int(rng.integers(1, 2 ** 30))
    # pictures
    pics = []
    for _ in range(int(rng.integers(0, 4))):
        face = pick(rng, [2, 3, 4])
        if face == 4:
            pu0 = U(rng, -wl + 0.2, wr - 1.2)
        else:
            pu0 = U(rng, 0.8, D - 1.2)
        pw_, ph_ = U(rng, 0.3, 1.0), U(rng, 0.3, 0.9)
        pv0 = U(rng, 1.2, Hr - 0.3 - ph_)
        if face == wface and not (pu0 + pw_ < wu0 - 0.5 or pu0 > wu1 + 0.5):
            continue
        img = cv2.resize(rng.random((4, 5, 3)).astype(F) ** 1.5, (50, 40), interpolation=cv2.INTER_CUBIC)
        pics.append((face, pu0, pu0 + pw_, pv0, pv0 + ph_, np.clip(img, 0.03, 0.9) * 0.7))
    # door
    dface = pick(rng, [2, 3])
    du0 = U(rng, 0.5, D - 1.3)
    door = (dface, du0, du0 + 0.9, 0, 2.05)
    door_c = pick(rng, [col(0.6, 0.6, 0.58), col(0.3, 0.2, 0.12)])

    # --- room surfaces
    dx = cam.dx[None, :]
    dy = cam.dy[:, None]
    tx = np.where(dx > 0, wr / dx, -wl / dx)
    ty = np.where(dy > 0, (Hr - hc) / dy, -hc / dy)
    t = np.minimum(np.minimum(tx, ty), D).astype(F)
    isx = tx <= np.minimum(ty, D)
    isy = (~isx) & (ty <= D)
    nid = np.where(isx, np.where(dx > 0, 3, 2), np.where(isy, np.where(dy > 0, 6, 1), 4)).astype(np.uint8)
    nid = np.broadcast_to(nid, (H, W))
    X = (dx * t).astype(F)
    Y = (hc + dy * t).astype(F)
    Z = t
    u = np.where((nid == 2) | (nid == 3), Z, X)
    v = np.where((nid == 1) | (nid == 6), Z, Y)
    pxm = (t / f).astype(F)
    tA, tB = S.texA, S.texB
    alb = np.zeros((H, W, 3), F)
    # walls
    wallm = (nid >= 2) & (nid <= 5)
    wa = wall_c * np.clip(1 + 0.05 * tA + 0.04 * tB, 0.5, 1.5)[..., None]
    if stripes:
        wa *= (1 + 0.08 * np.sign(np.sin(u * U(rng, 12, 30))))[..., None]
    skirt = interval_cov(v, pxm, -1, 0.1)
    wa = wa * (1 - skirt[..., None]) + col(0.6, 0.6, 0.58) * skirt[..., None]
    alb[wallm] = wa[wallm]
    # floor
    fm = nid == 1
    if floor_kind == 'wood':
        pwid = U(rng, 0.12, 0.22)
        pl = np.floor(X / pwid).astype(np.int64)
        plen = U(rng, 1.0, 2.2)
        zoff = hash01(pl, 0, 5) * plen
        seg = np.floor((Z + zoff) / plen).astype(np.int64)
        var = 0.75 + 0.5 * hash01(pl, seg, 7)
        seam = np.maximum(box_cov(X / pwid, pxm / pwid, 0, 0.04),
                          box_cov((Z + zoff) / plen, (t * t / (f * hc)) / plen, 0, 0.01))
        fa = floor_c * (var * (1 + 0.15 * tB) * (1 - 0.5 * seam))[..., None]
    elif floor_kind == 'tile':
        ts = U(rng, 0.3, 0.6)
        g = np.maximum(box_cov(X / ts, pxm / ts, 0, 0.03), box_cov(Z / ts, (t * t / (f * hc)) / ts, 0, 0.03))
        fa = floor_c * ((1 + 0.06 * tA) * (1 - 0.4 * g))[..., None]
    else:
        fa = floor_c * np.clip(1 + 0.12 * tA + 0.2 * tB, 0.4, 2)[..., None]
    if chance(rng, 0.5):  # rug
        rx0, rz0 = U(rng, -wl + 0.5, 0.5), U(rng, 1.5, D - 2.5)
        rx1, rz1 = rx0 + U(rng, 1.2, 2.5), rz0 + U(rng, 1.2, 2.0)
        rc = pick(rng, [col(0.5, 0.15, 0.1), col(0.2, 0.25, 0.45), col(0.55, 0.5, 0.4)])
        rm = (X > rx0) & (X < rx1) & (Z > rz0) & (Z < rz1)
        border = (X < rx0 + 0.12) | (X > rx1 - 0.12) | (Z < rz0 + 0.12) | (Z > rz1 - 0.12)
        rugc = np.where(border[..., None], rc * 0.5, rc * np.clip(1 + 0.3 * tB, 0.5, 1.5)[..., None])
        fa = np.where(rm[..., None], rugc, fa)
    alb[fm] = fa[fm]
    cm = nid == 6
    alb[cm] = (ceil_c * np.clip(1 + 0.03 * tA, 0.8, 1.2)[..., None])[cm]
    L = np.zeros((H, W, 3), F)
    kind = np.full((H, W), K_BUILD, np.uint8)
    # pictures & door
    for (face, a0, a1, b0, b1, img) in pics:
        m = (nid == face) & (u > a0) & (u < a1) & (v > b0) & (v < b1)
        if not m.any():
            continue
        uu = (u[m] - a0) / (a1 - a0)
        if face == 2:
            uu = 1 - uu
        vv = (b1 - v[m]) / (b1 - b0)
        fr = (uu < 0.06) | (uu > 0.94) | (vv < 0.07) | (vv > 0.93)
        pc_ = img[np.clip((vv * 39).astype(int), 0, 39), np.clip((uu * 49).astype(int), 0, 49)]
        alb[m] = np.where(fr[:, None], col(0.08, 0.06, 0.04), pc_)
    (face, a0, a1, b0, b1) = door
    m = (nid == face) & (u > a0) & (u < a1) & (v < b1)
    fr = m & ((u < a0 + 0.07) | (u > a1 - 0.07) | (v > b1 - 0.07))
    alb[m] = door_c * np.clip(1 + 0.05 * tB[m], 0.8, 1.2)[:, None]
    alb[fr] = frame_c
    # window
    wm = (nid == wface) & (u > wu0) & (u < wu1) & (v > wv0) & (v < wv1)
    iy, ix = np.nonzero(wm)
    if iy.size:
        uu, vv = u[iy, ix], v[iy, ix]
        ddx, ddy = cam.dx[ix], cam.dy[iy]
        if wface == 2:   # looking out to -X / +X: use a rotated azimuth
            azm = np.arctan2(1.0, -ddx) - 1.57
        elif wface == 3:
            azm = np.arctan2(1.0, ddx) - 1.57
        else:
            azm = np.arctan(ddx)
        nrm = np.sqrt(1 + ddx * ddx)
        el = np.arctan(ddy / nrm)
        outv = sky_base(np.tan(np.maximum(el, 0)), outP)
        top = np.interp(azm, az, prof)
        bld = el < top
        ka, kv = 150.0, 260.0
        ia, iv_ = np.floor(azm * ka).astype(np.int64), np.floor(el * kv).astype(np.int64)
        fa_, fv_ = azm * ka - ia, el * kv - iv_
        hw_ = hash01(ia, iv_, osalt)
        win = (hw_ < 0.16) & (fa_ > 0.2) & (fa_ < 0.75) & (fv_ > 0.25) & (fv_ < 0.7) & (el < top - 0.004)
        bcol = (WINDOW_PAL[(hash01(ia, iv_, osalt + 1) * 6).astype(int)]
                * (0.3 + 2.5 * hash01(ia, iv_, osalt + 2))[:, None])
        bval = np.where(win[:, None], bcol, col(0.004, 0.004, 0.005) * (1 + 0.3 * tA[iy, ix])[:, None])
        below = el < -0.01
        gl = hash01(np.floor(azm * 400).astype(np.int64), np.floor(el * 400).astype(np.int64), osalt + 3)
        gval = np.where((gl < 0.015)[:, None], STREET['sodium_hp'] * (2 + 20 * gl[:, None] / 0.015),
                        col(0.003, 0.0025, 0.002))
        outv = np.where(bld[:, None], bval, outv)
        outv = np.where(below[:, None], gval, outv)
        # stars
        st = (hash01(np.floor(azm * 700).astype(np.int64), np.floor(el * 700).astype(np.int64), osalt + 4)
              < 0.0015) & ~bld
        outv = outv + st[:, None] * 2.0
        # mullions / frame
        fu = (uu - wu0) / (wu1 - wu0)
        fvv = (vv - wv0) / (wv1 - wv0)
        pp = pxm[iy, ix]
        frm = interval_cov(uu - wu0, pp, -1, 0.06) + interval_cov(wu1 - uu, pp, -1, 0.06) + \
            interval_cov(vv - wv0, pp, -1, 0.06) + interval_cov(wv1 - vv, pp, -1, 0.06)
        if mull:
            frm = frm + interval_cov(np.abs(fu - 0.5) * (wu1 - wu0), pp, -1, 0.03) + \
                interval_cov(np.abs(fvv - 0.62) * (wv1 - wv0), pp, -1, 0.025)
        frm = np.clip(frm, 0, 1)[:, None]
        L[iy, ix] = outv * (1 - frm)
        alb[iy, ix] = 0.02 * (1 - frm) + frame_c * frm
        kind[iy, ix] = np.where(frm[:, 0] > 0.5, K_BUILD, K_GLASS)
    if curtains:
        cw_ = U(rng, 0.3, 0.7)
        ov = U(rng, 0.0, 0.3)
        cmk = (nid == wface) & (v > wv0 - 0.3) & (v < wv1 + 0.25) & \
            (((u > wu0 - cw_) & (u < wu0 + ov)) | ((u > wu1 - ov) & (u < wu1 + cw_)))
        fold = 0.55 + 0.45 * np.sin(u * U(rng, 25, 45)) ** 2
        alb[cmk] = (curtain_c * fold[..., None])[cmk]
        L[cmk] = 0
        kind[cmk] = K_OBJ
    S.Z[:] = Z
    S.X[:] = X
    S.Y[:] = Y
    S.N[:] = nid
    S.K[:] = kind
    S.A[:] = alb
    S.L[:] = L

    # --- furniture
    def wood():
        return Plain(pick(rng, [col(0.3, 0.18, 0.09), col(0.15, 0.1, 0.06), col(0.5, 0.4, 0.28),
                                col(0.6, 0.6, 0.58)]), 0.0, 0.15)
    boxes = []

    def B_(a, b, m, k=K_OBJ):
        paint_box(S, a, b, m, k)
        boxes.append((a, b))
    layout = pick(rng, ['living', 'bedroom', 'dining'])
    tops = []   # surfaces for table lamps/candles: (x, y, z)
    if layout == 'living':
        sc = Plain(pick(rng, [col(0.3, 0.3, 0.32), col(0.5, 0.2, 0.15), col(0.2, 0.3, 0.25),
                              col(0.55, 0.5, 0.42)]), 0.0, 0.2)
        zc = U(rng, 2.0, D - 1.5)
        B_((-wl, 0, zc - 1.0), (-wl + 0.9, 0.45, zc + 1.0), sc)
        B_((-wl, 0.45, zc - 1.0), (-wl + 0.25, 0.9, zc + 1.0), sc)
        B_((-wl, 0.45, zc - 1.0), (-wl + 0.9, 0.65, zc - 0.8), sc)
        B_((-wl, 0.45, zc + 0.8), (-wl + 0.9, 0.65, zc + 1.0), sc)
        tm = wood()
        tx0 = -wl + 1.4
        B_((tx0, 0.38, zc - 0.5), (tx0 + 0.6, 0.43, zc + 0.5), tm)
        for (a, b) in [(tx0, zc - 0.5), (tx0 + 0.55, zc - 0.5), (tx0, zc + 0.45), (tx0 + 0.55, zc + 0.45)]:
            B_((a, 0, b), (a + 0.05, 0.38, b + 0.05), tm)
        tops.append((tx0 + 0.3, 0.43, zc))
        sx0 = U(rng, -wl + 0.2, wr - 1.8)
        B_((sx0, 0, D - 0.45), (sx0 + 1.6, 0.8, D), wood())
        tops.append((sx0 + 0.3, 0.8, D - 0.22))
        if chance(rng, 0.6):
            scr = Screen(rng, 4, LU(rng, 0.5, 4.0), pick(rng, [col(0.6, 0.75, 1.0), col(1, 1, 1), col(1.0, 0.8, 0.6)]))
            B_((sx0 + 0.6, 0.85, D - 0.3), (sx0 + 1.5, 1.38, D - 0.25), scr)
            S.lights.append(Light((sx0 + 1.05, 1.1, D - 0.6), col(0.6, 0.75, 1.0), I=U(rng, 0.2, 0.8), mode='dir',
                                  axis=(0, 0, -1), k=1, spill=0.1))
        if chance(rng, 0.6):
            bz = U(rng, 0.5, D - 1.6)
            bm = Plain(col(0.3, 0.2, 0.12), 0.0, 0.1)
            B_((wr - 0.35, 0, bz), (wr, 2.0, bz + 1.2), bm)
            for k_ in range(5):   # shelves of books (as coloured strips)
                yb = 0.1 + k_ * 0.38
                z_ = bz + 0.03
                while z_ < bz + 1.15:
                    bw = U(rng, 0.02, 0.06)
                    paint_box(S, (wr - 0.37, yb, z_), (wr - 0.08, yb + U(rng, 0.2, 0.32), z_ + bw),
                              Plain(col(*rng.uniform(0.05, 0.6, 3)), 0.0, 0.1), K_OBJ)
                    z_ += bw + 0.003
    elif layout == 'bedroom':
        bx = U(rng, -wl + 1.0, wr - 1.0)
        bc = Plain(pick(rng, [col(0.7, 0.7, 0.68), col(0.5, 0.55, 0.65), col(0.6, 0.45, 0.4)]), 0.0, 0.15)
        B_((bx - 0.8, 0, D - 2.1), (bx + 0.8, 0.5, D), bc)
        B_((bx - 0.85, 0, D - 0.08), (bx + 0.85, 1.1, D), wood())
        B_((bx - 0.7, 0.5, D - 0.55), (bx - 0.05, 0.65, D - 0.15), Plain(col(0.8, 0.8, 0.78), 0.0))
        B_((bx + 0.05, 0.5, D - 0.55), (bx + 0.7, 0.65, D - 0.15), Plain(col(0.8, 0.8, 0.78), 0.0))
        for s in (-1, 1):
            nx = bx + s * 1.15
            B_((nx - 0.25, 0, D - 0.45), (nx + 0.25, 0.55, D), wood())
            tops.append((nx, 0.55, D - 0.22))
        if chance(rng, 0.6):
            wz = U(rng, 0.5, D - 3.0)
            B_((wr - 0.6, 0, wz), (wr, 2.1, wz + 1.5), wood())
    else:
        tm = wood()
        tz = U(rng, 2.5, D - 1.5)
        tx = U(rng, -0.5, 0.5)
        B_((tx - 0.8, 0.72, tz - 0.45), (tx + 0.8, 0.76, tz + 0.45), tm)
        for (a, b) in [(tx - 0.75, tz - 0.4), (tx + 0.7, tz - 0.4), (tx - 0.75, tz + 0.35), (tx + 0.7, tz + 0.35)]:
            B_((a, 0, b), (a + 0.05, 0.72, b + 0.05), tm)
        for s in (-1, 1):
            for cz in (tz - 0.25, tz + 0.25):
                cx = tx + s * 1.0
                B_((cx - 0.22, 0.45, cz - 0.2), (cx + 0.22, 0.5, cz + 0.2), tm)
                bx0 = cx + 0.18 if s > 0 else cx - 0.22
                B_((bx0, 0.5, cz - 0.2), (bx0 + 0.04, 1.0, cz + 0.2), tm)
        tops.append((tx + U(rng, -0.4, 0.4), 0.76, tz))
        # pendant over the table
        S.pendant_over = (tx, tz)
        if chance(rng, 0.5):
            B_((wr - 0.6, 0, 0.8), (wr, 0.9, D - 0.5), Plain(col(0.7, 0.7, 0.68), 0.0, 0.05))
            tops.append((wr - 0.3, 0.9, U(rng, 1.5, D - 1)))
    # --- lights
    lk = list(INDOOR.keys())
    main_c = INDOOR[pick(rng, lk[:4])]
    nl = 0
    if layout == 'dining' or chance(rng, 0.5):   # pendant bulb(s)
        px_, pz_ = getattr(S, 'pendant_over', (U(rng, -wl + 0.8, wr - 0.8), U(rng, 1.8, D - 1.0)))
        npend = 1 if chance(rng, 0.6) else 3
        for j in range(npend):
            xx = px_ + (j - (npend - 1) / 2) * 0.6
            yy = Hr - U(rng, 0.5, 1.0)
            shade = chance(rng, 0.5)
            paint_box(S, (xx - 0.006, yy, pz_ - 0.006), (xx + 0.006, Hr, pz_ + 0.006),
                      Plain(col(0.05, 0.05, 0.05), 0.0), K_FIXT)
            if shade:
                paint_box(S, (xx - 0.2, yy + 0.02, pz_ - 0.2), (xx + 0.2, yy + 0.25, pz_ + 0.2),
                          Plain(pick(rng, [col(0.05, 0.05, 0.05), col(0.6, 0.6, 0.6), col(0.1, 0.2, 0.15)]),
                                0.0, 0.05), K_FIXT)
                S.lights.append(Light((xx, yy, pz_), main_c, I=U(rng, 3, 10), mode='dir', axis=(0, -1, 0), k=1.5,
                                      spill=0.05, excl=0.3, soft=0.2, B=LU(rng, 300, 3000), r_m=0.04,
                                      glow=LU(rng, 0.01, 0.06), glow_r=U(rng, 4, 10), ztol=0.05))
            else:
                S.lights.append(Light((xx, yy - 0.05, pz_), main_c, I=U(rng, 1.5, 6), mode='iso', excl=0.1, soft=0.2,
                                      B=LU(rng, 300, 3000), r_m=0.045, glow=LU(rng, 0.01, 0.1), glow_r=U(rng, 3, 8),
                                      halo=LU(rng, 0.003, 0.02), halo_r=U(rng, 15, 40)))
            nl += 1
    if chance(rng, 0.35):   # recessed downlights
        for j in range(int(rng.integers(2, 6))):
            xx, zz = U(rng, -wl + 0.5, wr - 0.5), U(rng, 1.0, D - 0.5)
            S.lights.append(Light((xx, Hr - 0.01, zz), INDOOR[pick(rng, lk)], I=U(rng, 1.5, 4), mode='dir',
                                  axis=(0, -1, 0), k=U(rng, 2, 5), spill=0.0, soft=0.2, B=LU(rng, 300, 3000), r_m=0.04,
                                  glow=LU(rng, 0.005, 0.05), glow_r=U(rng, 3, 8), ztol=0.05))
            nl += 1
    for (tx_, ty_, tz_) in tops:   # table lamps with glowing fabric shade
        if chance(rng, 0.55):
            c = INDOOR[pick(rng, ['incandescent', 'halogen', 'warm_led'])]
            sh_e = LU(rng, 0.8, 8)
            hs = U(rng, 0.22, 0.34)
            paint_box(S, (tx_ - 0.02, ty_, tz_ - 0.02), (tx_ + 0.02, ty_ + 0.3, tz_ + 0.02),
                      Plain(col(0.3, 0.25, 0.2), 0.0), K_FIXT)
            paint_box(S, (tx_ - hs / 2, ty_ + 0.28, tz_ - hs / 2), (tx_ + hs / 2, ty_ + 0.28 + hs * 0.8, tz_ + hs / 2),
                      Plain(col(0, 0, 0), 0.0, 0.0, emit=c * sh_e * col(1.0, 0.95, 0.85)), K_FIXT)
            S.lights.append(Light((tx_, ty_ + 0.28 + hs * 0.4, tz_), c, I=U(rng, 1.5, 5), mode='updown', k=1.5,
                                  spill=0.15, excl=0.3, soft=0.2))
            nl += 1
        elif chance(rng, 0.3):   # candle
            S.lights.append(Light((tx_, ty_ + 0.12, tz_), col(1.0, 0.55, 0.18), I=U(rng, 0.05, 0.2), mode='iso',
                                  soft=0.1, B=LU(rng, 10, 50), r_px=U(rng, 1.0, 2.5), glow=LU(rng, 0.03, 0.1),
                                  glow_r=U(rng, 3, 8), ztol=0.05))
            paint_box(S, (tx_ - 0.03, ty_, tz_ - 0.03), (tx_ + 0.03, ty_ + 0.1, tz_ + 0.03),
                      Plain(col(0.8, 0.78, 0.7), 0.0), K_OBJ)
    if nl == 0 or chance(rng, 0.3):   # floor lamp
        fx, fz = pick(rng, [(-wl + 0.4, U(rng, 1.5, D - 0.5)), (wr - 0.4, U(rng, 1.5, D - 0.5))])
        c = INDOOR[pick(rng, lk[:3])]
        paint_box(S, (fx - 0.02, 0, fz - 0.02), (fx + 0.02, 1.45, fz + 0.02), Plain(col(0.1, 0.1, 0.1), 0.0), K_FIXT)
        paint_box(S, (fx - 0.2, 1.4, fz - 0.2), (fx + 0.2, 1.7, fz + 0.2),
                  Plain(col(0, 0, 0), 0.0, 0.0, emit=c * LU(rng, 1, 8)), K_FIXT)
        S.lights.append(Light((fx, 1.55, fz), c, I=U(rng, 2, 6), mode='updown', k=1.5, spill=0.2, excl=0.3, soft=0.2))
    if chance(rng, 0.3):   # fairy lights along a wall top
        face = pick(rng, [2, 3])
        xw = -wl + 0.02 if face == 2 else wr - 0.02
        zz = np.linspace(U(rng, 0.8, 2), D - 0.3, int(U(rng, 20, 50)))
        yy = Hr - 0.3 - 0.25 * np.abs(np.sin((zz - zz[0]) * U(rng, 1.5, 3)))
        c = pick(rng, [col(1.0, 0.75, 0.4), col(1.0, 0.85, 0.6), NEON['blue'], NEON['pink']])
        bb = LU(rng, 20, 200)
        for z_, y_ in zip(zz, yy):
            S.lights.append(Light((xw, y_, z_), c, B=bb, r_px=U(rng, 1.0, 1.8), glow=LU(rng, 0.02, 0.08),
                                  glow_r=U(rng, 2, 5), ztol=0.1, spikes=False))
        S.lights.append(Light((xw, Hr - 0.4, zz.mean()), c, I=0.4, mode='iso', soft=0.5))
    # ambient fill (inter-reflections) with crude ambient occlusion
    tot = sum((Lt.I * Lt.col for Lt in S.lights if Lt.I > 0), np.zeros(3, F))
    fill = tot * U(rng, 0.01, 0.03) + outP['hor'] * 2
    dists = [S.X + wl, wr - S.X, S.Y, Hr - S.Y, D - S.Z]
    ao = np.ones((H, W), F)
    for dd in dists:
        ao *= 1 - 0.45 * np.exp(-np.maximum(dd, 0) / 0.35) * (dd > 0.02)
    for (a, b) in boxes:   # contact darkening around furniture on floor/walls
        if b[1] > 0.3 and a[1] < 0.05:
            ddx = np.maximum(np.maximum(a[0] - S.X, S.X - b[0]), 0)
            ddz = np.maximum(np.maximum(a[2] - S.Z, S.Z - b[2]), 0)
            dd = np.sqrt(ddx * ddx + ddz * ddz)
            ao *= 1 - 0.5 * np.exp(-dd / 0.2) * (S.Y < 0.05)
    S.amb_fill = (ao[..., None] * fill[None, None, :]).astype(F)
    S.haze = LU(rng, 0.0005, 0.004)
    if chance(rng, 0.2):
        S.spikes = dict(n=pick(rng, [4, 6, 8]), ang=U(rng, 0, math.pi), amp=LU(rng, 0.002, 0.008),
                        len=U(rng, 0.7, 1.4), thr=LU(rng, 3000, 10000))
    glass = S.K == K_GLASS

    def post(S, img):
        # faint mirror images of the room's lamps in the dark window glass
        tmp = np.zeros_like(img)
        for Lt in S.lights:
            if Lt.B <= 0:
                continue
            p = Lt.pos.copy()
            if wface == 4:
                p[2] = 2 * D - p[2]
            elif wface == 2:
                p[0] = -2 * wl - p[0]
            else:
                p[0] = 2 * wr - p[0]
            draw_light(S, tmp, Lt, pos=p, scale=0.05, ztest=False)
        img += tmp * glass[..., None]
    return finish(S, post_light=post)


BUILDERS = {'avenue': build_avenue, 'across': build_across, 'skyline': build_skyline, 'park': build_park,
            'interior': build_interior}


# ----------------------------------------------------------------------------- io / main
def write_exr(path, img):
    hdr = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(hdr, {"RGB": np.ascontiguousarray(img, dtype=np.float32)}).write(path)


def read_exr(path):
    with OpenEXR.File(path) as f:
        ch = f.channels()
        if "RGB" in ch:
            return np.asarray(ch["RGB"].pixels, np.float32)
        return np.stack([np.asarray(ch[c].pixels, np.float32) for c in "RGB"], -1)


def schedule(seed, count):
    rng = np.random.default_rng([seed, 424242])
    kinds = []
    outdoor = ['avenue', 'across', 'skyline', 'park', 'avenue']
    oi = 0
    block_out = list(rng.permutation(outdoor))
    for b0 in range(0, count, 6):
        n = min(6, count - b0)
        ipos = int(rng.integers(0, 6))
        for j in range(n):
            if j == ipos:
                kinds.append('interior')
            else:
                if oi >= len(block_out):
                    block_out = list(rng.permutation(outdoor))
                    oi = 0
                kinds.append(block_out[oi])
                oi += 1
    return kinds


def scene_name(idx):
    """File name of scene ``idx`` without its .exr suffix."""
    return "night-gen-%03d" % idx


def _work(args):
    idx, seed, kind, out = args
    cv2.setNumThreads(1)
    t0 = time.time()
    rng = np.random.default_rng([seed, idx, 7919])
    img = BUILDERS[kind](rng)
    name = scene_name(idx) + ".exr"
    path = os.path.join(out, name)
    write_exr(path, img)
    back = read_exr(path)
    assert back.shape == (H, W, 3) and np.array_equal(back, img), "EXR read-back mismatch"
    lum = back @ LUMW
    st = dict(name=name, kind=kind, min=float(lum.min()), med=float(np.median(lum)),
              p99=float(np.percentile(lum, 99)), max=float(lum.max()), frac=float((lum > 1.0).mean()),
              finite=bool(np.isfinite(back).all()), neg=bool((back < 0).any()), t=time.time() - t0)
    thumb = cv2.resize(back, (256, 256), interpolation=cv2.INTER_AREA)
    return st, thumb


def _at_least_one(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError("not a whole number: %r" % text) from None
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1, got %d" % value)
    return value


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--count', type=_at_least_one, default=24, metavar='N', help='number of scenes (default 24)')
    ap.add_argument('--seed', type=int, default=0, metavar='N', help='the reported set is seed 7 (default 0)')
    ap.add_argument('--out', required=True, metavar='DIR', help='folder for the EXRs (created if missing)')
    ap.add_argument('--jobs', type=_at_least_one, default=min(2, os.cpu_count() or 1), metavar='N',
                    help='worker processes (default min(2, CPUs)); the output does not depend on it')
    ap.add_argument('--contact', default=None, metavar='PATH', help='also write a contact-sheet PNG here')
    ap.add_argument('--overwrite', action='store_true', help='replace scenes already in --out')
    a = ap.parse_args(argv)
    if os.path.exists(a.out) and not os.path.isdir(a.out):
        print("independent_night_scenes: --out %s exists and is not a folder" % a.out, file=sys.stderr)
        return 1
    present = [name for name in (scene_name(i) + '.exr' for i in range(a.count))
               if os.path.exists(os.path.join(a.out, name))]
    if present and not a.overwrite:
        print("independent_night_scenes: --out %s already holds %s (and %d more): --overwrite replaces them"
              % (a.out, present[0], len(present) - 1), file=sys.stderr)
        return 1
    try:
        os.makedirs(a.out, exist_ok=True)
    except OSError as e:
        print("independent_night_scenes: cannot create --out %s: %s" % (a.out, e.strerror or e), file=sys.stderr)
        return 1
    kinds = schedule(a.seed, a.count)
    tasks = [(i, a.seed, kinds[i], a.out) for i in range(a.count)]
    t0 = time.time()
    results = []
    if a.jobs > 1:
        with mp.get_context('fork').Pool(a.jobs) as pool:
            for st, th in pool.imap(_work, tasks):
                results.append((st, th))
                print_stats(st)
    else:
        for tk in tasks:
            st, th = _work(tk)
            results.append((st, th))
            print_stats(st)
    sheet_note = ''
    if a.contact:
        cols, rows = 6, int(math.ceil(a.count / 6))
        sheet = np.zeros((rows * 256, cols * 256, 3), F)
        for i, (st, th) in enumerate(results):
            r, c = divmod(i, cols)
            sheet[r * 256:(r + 1) * 256, c * 256:(c + 1) * 256] = th
        tm = (sheet / (1 + sheet)) ** (1 / 2.2)
        try:
            ok = cv2.imwrite(a.contact, np.clip(tm[..., ::-1] * 255 + 0.5, 0, 255).astype(np.uint8))
        except cv2.error:
            ok = False
        if not ok:
            print("independent_night_scenes: could not write the contact sheet %s" % a.contact, file=sys.stderr)
            return 1
        sheet_note = ', contact sheet %s' % a.contact
    print("wrote %d scenes to %s%s, %.1f s total" % (a.count, a.out, sheet_note, time.time() - t0))
    return 0


def print_stats(st):
    flag = '' if st['finite'] and not st['neg'] else '  !! non-finite or negative'
    print("%s  %-8s  min %.3g  median %.4g  p99 %.4g  max %.5g  frac>1 %.4f  (%.1fs)%s" % (
        st['name'], st['kind'], st['min'], st['med'], st['p99'], st['max'], st['frac'], st['t'], flag), flush=True)


if __name__ == '__main__':
    sys.exit(main())
