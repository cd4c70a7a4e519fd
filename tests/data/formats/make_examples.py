"""Make the synthetic example files (run from the repository root:
``python tests/data/formats/make_examples.py``). They are in the published formats; their values
are simulated (stated in their headers), so their truth is known:

- ``cssat/data/examples/mmt_rocket_body_synthetic.txt`` (shipped in the package: the README's and
  the smoke run's example, and the tests'): an MMT-9 whole-object export (format of the MMT database:
  ``# key: value`` header, column names in a comment line, date and time as two fields, two
  camera channels interleaved 7 ms apart) of a double-peaked rocket-body curve with a 18.888 s
  rotation (two unequal maxima a turn), 0.05 mag noise and a slow drift, two tracks.
- ``lightcurve_tt.ecsv``: an astropy ECSV table whose time column is a ``Time`` in TT.
"""

import numpy as np

rng = np.random.default_rng(34)


def rocket_body(t, period=18.888):
    w = 2 * np.pi * t / period
    return 7.0 - 0.25 * np.cos(w + 0.4) - 0.6 * np.cos(2 * w) - 0.12 * np.cos(3 * w + 1.0) + 0.002 * t


lines = ["# satellite: 99001 SYNTHETIC R/B / --", "# catalogue: 1 NORAD", "# variability: 2 Periodic",
         "# variability_period: 18.888", "# type: 2 R/B Rocket body (synthetic: cssat tests/data/formats/make_examples.py)",
         "# npoints: 1200", "#", "# Date Time StdMag Mag Filter Penumbra Distance Phase Channel Track"]
t0 = np.datetime64("2021-03-04T21:10:05.000", "ms")
for track, start in ((101, 0.0), (102, 900.0)):
    for i in range(300):
        for ch, off in ((3, 0.0), (4, 0.007)):
            t = start + 0.2 * i + off
            mag = rocket_body(t) + rng.normal(0, 0.05)
            dist = 2000.0 + 0.5 * t
            std = mag - 5 * np.log10(dist / 1000.0)
            stamp = str(t0 + np.timedelta64(int(round(t * 1000)), "ms")).replace("T", " ")
            lines.append(f"{stamp}000 {std:.3f} {mag:.5f} Clear 0 {dist:.3f} 61.5 {ch} {track}")
open("cssat/data/examples/mmt_rocket_body_synthetic.txt", "w").write("\n".join(lines) + "\n")

from astropy.table import Table  # noqa: E402
from astropy.time import Time  # noqa: E402
import astropy.units as u  # noqa: E402

t = np.arange(0, 600.0, 1.0)
tab = Table({"time": Time("2020-04-01T21:00:00", scale="tt") + t * u.s,
             "mag": (9.0 + 0.3 * np.sin(2 * np.pi * t / 75.0) + rng.normal(0, 0.02, t.size)) * u.mag,
             "mag_err": np.full(t.size, 0.02) * u.mag})
tab.meta.update(object="SYNTHETIC", norad=99002, comment="synthetic: a 75 s sinusoid, time in TT")
tab.write("tests/data/formats/lightcurve_tt.ecsv", format="ascii.ecsv", overwrite=True)
