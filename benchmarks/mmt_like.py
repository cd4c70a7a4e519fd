"""Synthetic Mini-MegaTORTORA (MMT-9)-like satellite tracks for the period benchmark.

Real periodic MMT tracks are not available offline; :func:`make_tracks` draws tracks that copy
what the native MMT exports look like (``tests/data/real/mmt_*.txt``):

* **Cadence** 0.1 s (10 Hz), stamps rounded to the millisecond; 100–2000 samples in all.
* **Two camera channels** (30 % of tracks): a second channel, stamped separately 1–14 ms after
  the first, overlaps the first for part of the track (20–100 % of it), with its own noise and —
  in half of those tracks, as in the real Starlink track of ``tests/data`` — its own zero-point
  offset of up to ±0.2 mag (``channel_offset=False`` leaves it out).
* **Gaps** (30 % of tracks): 1–3 stretches of 1–5 s with no samples.
* **Noise**: white, 0.02–0.15 mag (log-uniform); in half of the tracks a slow drift (range and
  phase-angle changes): a linear or a quadratic trend of up to 0.3 mag over the track.

Kinds (``label``/``kind``):

* ``periodic``/``rocket``: a double-peaked curve, two unequal maxima a turn: a fundamental
  (15–50 % of the 2nd harmonic), a dominant 2nd harmonic and 1–4 weaker higher ones, random
  phases; peak-to-peak 0.2–1.5 mag.
* ``periodic``/``glint``: a weak base curve (0.05–0.3 mag, fundamental + 2nd harmonic) plus 1–4
  narrow glints a turn: Gaussians of 1σ width 1–5 % of the period, brightening by 0.5–3 mag,
  unequal heights.
* ``periodic``/``sine``: a sinusoid (0.1–1 mag peak-to-peak) with a 2nd harmonic of ≤ 10 %.
* ``nonvariable``/``nonvariable``: a constant plus the noise (and drift).
* ``aperiodic``/``ou`` or ``aperiodic``/``randomwalk``: red noise — an Ornstein–Uhlenbeck
  process of correlation time 2–30 s or a random walk, 0.1–0.5 mag rms — plus the noise (and drift).

Periods are log-uniform in 1–60 s and at most ``span/2.5`` (≥ 2.5 cycles a track); ``period_s``
is the whole rotation's period (for a double-peaked curve the period of the whole curve, not half).
"""

from __future__ import annotations

import numpy as np

CADENCE_S = 0.1

KINDS = {  # kind: (label, probability)
    "rocket": ("periodic", 0.22),
    "glint": ("periodic", 0.16),
    "sine": ("periodic", 0.12),
    "nonvariable": ("nonvariable", 0.25),
    "ou": ("aperiodic", 0.15),
    "randomwalk": ("aperiodic", 0.10),
}


def _loguniform(rng, a, b):
    return float(np.exp(rng.uniform(np.log(a), np.log(b))))


def _times(rng, n_target):
    """Sample stamps (s), channel index and metadata for a track of about ``n_target`` samples."""
    two = rng.random() < 0.3
    cover = rng.uniform(0.2, 1.0) if two else 0.0
    n_main = int(round(n_target / (1.0 + cover)))
    n_main = max(n_main, 60)
    # gaps: extend the grid and cut holes so that the samples left are about n_main
    n_gaps = int(rng.integers(1, 4)) if rng.random() < 0.3 else 0
    gap_len = [int(round(rng.uniform(1.0, 5.0) / CADENCE_S)) for _ in range(n_gaps)]
    grid = np.arange(n_main + sum(gap_len))
    keep = np.ones(len(grid), bool)
    for g in gap_len:
        for _ in range(20):  # place the gap away from the ends and from other gaps
            s = int(rng.integers(len(grid) // 10, max(len(grid) * 9 // 10 - g, len(grid) // 10 + 1)))
            if keep[max(s - 5, 0):s + g + 5].all():
                keep[s:s + g] = False
                break
    t1 = grid[keep] * CADENCE_S + rng.uniform(0, 0.1)
    ch = np.zeros(len(t1), int)
    offset_ms = None
    if two:
        offset_ms = float(rng.uniform(1.0, 14.0))
        n2 = int(round(cover * len(t1)))
        start = int(rng.integers(0, len(t1) - n2 + 1))
        t2 = t1[start:start + n2] + offset_ms * 1e-3
        t1 = np.r_[t1, t2]
        ch = np.r_[ch, np.ones(len(t2), int)]
    t = np.round(t1, 3)
    o = np.argsort(t, kind="stable")
    t, ch = t[o], ch[o]
    # at most 2000 samples
    if len(t) > 2000:
        t, ch = t[:2000], ch[:2000]
    return t, ch, {"two_channels": two, "channel_offset_ms": offset_ms, "n_gaps": n_gaps}


def _rocket(rng, phi):
    n_hi = int(rng.integers(1, 5))
    amps = [rng.uniform(0.15, 0.5), 1.0] + [rng.uniform(0.05, 0.4) / (k - 1) for k in range(3, 3 + n_hi)]
    y = sum(a * np.cos(2 * np.pi * (k + 1) * phi + rng.uniform(0, 2 * np.pi)) for k, a in enumerate(amps))
    return y, {"harmonic_amps": [float(a) for a in amps]}


def _glint(rng, phi, P):
    base = rng.uniform(0.05, 0.3)
    y = 0.5 * base * (np.cos(2 * np.pi * phi + rng.uniform(0, 2 * np.pi))
                      + rng.uniform(0, 0.6) * np.cos(4 * np.pi * phi + rng.uniform(0, 2 * np.pi)))
    n_g = int(rng.integers(1, 5))
    centres = np.sort(rng.uniform(0, 1, n_g)) if n_g == 1 else None
    if n_g > 1:  # spread the glints: jittered around equal spacing
        centres = (np.arange(n_g) + rng.uniform(-0.3, 0.3, n_g)) / n_g + rng.uniform(0, 1)
    heights = rng.uniform(0.5, 3.0, n_g)
    if n_g > 1 and heights.max() / heights.min() < 1.3:  # unequal heights
        heights[int(rng.integers(0, n_g))] *= 0.6
    widths = rng.uniform(0.01, 0.05, n_g)
    for c, h, w in zip(centres % 1.0, heights, widths):
        d = (phi - c + 0.5) % 1.0 - 0.5
        y = y - h * np.exp(-0.5 * (d / w) ** 2)  # brighter = smaller magnitude
    return y, {"n_glints": n_g, "glint_mag": [float(h) for h in heights], "glint_width_frac": [float(w) for w in widths],
               "base_mag": float(base)}


def _sine(rng, phi):
    A = rng.uniform(0.1, 1.0)
    y = 0.5 * A * (np.cos(2 * np.pi * phi) + rng.uniform(0, 0.1) * np.cos(4 * np.pi * phi + rng.uniform(0, 2 * np.pi)))
    return y, {}


def _red(rng, t, kind):
    amp = rng.uniform(0.1, 0.5)
    dt = np.diff(t, prepend=t[0])
    x = np.empty(len(t))
    if kind == "ou":
        tau = rng.uniform(2.0, 30.0)
        x[0] = rng.normal()
        for i in range(1, len(t)):
            a = np.exp(-dt[i] / tau)
            x[i] = a * x[i - 1] + np.sqrt(1 - a * a) * rng.normal()
        meta = {"tau_s": float(tau)}
    else:
        x = np.cumsum(rng.normal(size=len(t)) * np.sqrt(np.maximum(dt, 1e-6)))
        x = x - x.mean()
        x = x / max(x.std(), 1e-12)
        meta = {}
    return amp * x, dict(meta, red_amp=float(amp))


def make_tracks(n: int = 100, seed: int = 0, channel_offset: bool = True) -> list[dict]:
    """``n`` MMT-like tracks (see the module's docstring), reproducible from ``seed``. Each is a
    dict: ``t`` (s, from 0, sorted), ``mag``, ``err`` (None), ``label`` (``"periodic"``,
    ``"aperiodic"`` or ``"nonvariable"``), ``period_s`` (float or None), ``kind`` and ``meta``
    (the draw's parameters: noise, drift, channels, gaps, shape)."""
    rng = np.random.default_rng(seed)
    names = list(KINDS)
    p = np.array([KINDS[k][1] for k in names])
    out = []
    for _ in range(n):
        kind = names[int(rng.choice(len(names), p=p / p.sum()))]
        label = KINDS[kind][0]
        n_target = int(rng.integers(100, 2001))
        t, ch, meta = _times(rng, n_target)
        t = t - t[0]
        span = float(t[-1])
        noise = _loguniform(rng, 0.02, 0.15)
        mag0 = rng.uniform(4.0, 10.0)
        y = np.zeros(len(t))
        period = None
        if label == "periodic":
            period = _loguniform(rng, 1.0, max(min(60.0, span / 2.5), 1.0 + 1e-9))
            phi = t / period + rng.uniform(0, 1)
            if kind == "rocket":
                s, extra = _rocket(rng, phi)
                A = rng.uniform(0.2, 1.5)
                s = A * s / np.ptp(s)  # peak-to-peak A (on the samples)
            elif kind == "glint":
                s, extra = _glint(rng, phi, period)
            else:
                s, extra = _sine(rng, phi)
            y += s
            meta.update(extra)
        elif label == "aperiodic":
            s, extra = _red(rng, t, kind)
            y += s
            meta.update(extra)
        drift = 0.0
        if rng.random() < 0.5:
            drift = rng.uniform(-0.3, 0.3)
            x = t / max(span, 1e-9)
            if rng.random() < 0.5:
                y += drift * x
                meta["drift"] = ("linear", float(drift))
            else:
                c = rng.uniform(0.2, 0.8)  # a parabola with its extreme inside or near the track
                q = (x - c) ** 2
                y += drift * (q - q.min()) / max(np.ptp(q), 1e-12)
                meta["drift"] = ("quadratic", float(drift))
        if meta["two_channels"] and channel_offset and rng.random() < 0.5:
            off = rng.uniform(-0.2, 0.2)
            y += off * (ch == 1)
            meta["channel_mag_offset"] = float(off)
        y += noise * rng.normal(size=len(t))
        meta.update(noise_mag=float(noise), n_samples=int(len(t)), span_s=span)
        out.append({"t": t, "mag": mag0 + y, "err": None, "label": label,
                    "period_s": None if period is None else float(period), "kind": kind, "meta": meta, "channels": ch})
    return out


if __name__ == "__main__":
    tr = make_tracks(20)
    for d in tr:
        print(d["label"], d["kind"], len(d["t"]), round(float(d["t"][-1]), 1), d["period_s"],
              {k: v for k, v in d["meta"].items() if k in ("two_channels", "n_gaps", "noise_mag", "drift")})
