"""Benchmark: the phase-screen sensing matrix Φ (64² pixels × 3277 samples) against what a
screen-and-propagation approach with aotools costs for the same samples, in one run.

* ``cssat phase_screen``: :class:`cssat.physics.PhaseScreenAtmosphere` builds the whole
  ``(3277, 4096)`` Φ (8 layers of HV 5/7, spectral synthesis of the Fresnel-filtered, pupil- and
  exposure-averaged log-amplitude at every pixel's direction).
* ``aotools screens + propagation``: per sample and layer one von Kármán phase screen
  (``ft_phase_screen``, 256² at 1 cm: a 2.56 m pupil plane) propagated to the ground by
  ``angularSpectrum`` — the least a screen-based simulation does before it can even form the
  pupil average of one direction. Timed on ``--peer-samples`` samples and scaled to 3277; it
  still lacks the 4096 directions, whose millimetre shifts at GEO such a grid cannot resolve.

Times are medians of ``--repeats`` runs. Run from the repository root::

    python benchmarks/atmosphere.py --threads 2 --repeats 3
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from _timing import median_time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--peer-samples", type=int, default=20)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    from cssat.physics import PhaseScreenAtmosphere

    m, n = 3277, 64 * 64
    atm = PhaseScreenAtmosphere()
    t_ours, times, op = median_time(lambda: atm.operator(m, n, seed=0, dtype=torch.float32), args.repeats)
    print(f"cssat phase_screen Φ ({m} × {n}, {atm.n_layers} layers): {t_ours:.2f} s (runs {', '.join(f'{t:.2f}' for t in times)})")
    w = op.matrix()
    print(f"  mean {float(w.mean()):.6f}, scintillation index {float(w.var(0).mean()):.3g} "
          f"(model {atm.scintillation_index:.3g})")
    try:
        import aotools
        from aotools.turbulence.phasescreen import ft_phase_screen
    except ImportError:
        print("aotools not installed: no peer timing (pip install aotools)")
        return
    lay = atm.layers()
    r0 = (0.423 * (2 * np.pi / 550e-9) ** 2 * lay.cn2dh) ** (-3 / 5)

    def peer():
        for s in range(args.peer_samples):
            for i in range(len(lay.height_m)):
                ph = ft_phase_screen(float(r0[i]), 256, 0.01, 25.0, 0.01, seed=s * 100 + i)
                aotools.opticalpropagation.angularSpectrum(np.exp(1j * ph), 550e-9, 0.01, 0.01, float(lay.height_m[i]))

    t_peer, _, _ = median_time(peer, args.repeats)
    scaled = t_peer * m / args.peer_samples
    print(f"aotools screens + propagation: {t_peer:.2f} s for {args.peer_samples} samples -> {scaled:.1f} s for {m} "
          f"(no directions yet)")
    print(f"ratio (aotools / cssat): {scaled / t_ours:.1f}x")


if __name__ == "__main__":
    main()
