"""A mesh in a scenario: the ``scenario`` group built into a :class:`~cssat.scene.Scenario` (the
element set checked against a measured file's object and epoch), a measured light curve read
(``observations=<file>`` with the ``observed`` settings) — what the forward models over a scene
(:mod:`cssat.experiments.forward.scene`, ``egi``, ``shadow``, ``observed``) share.
"""

from __future__ import annotations

import dataclasses
import logging
from typing import TYPE_CHECKING, Any

import numpy as np

from cssat._checks import FieldError, int_param
from cssat.experiments.build import settings
from cssat.scene import make_scenario
from cssat.scene.orbit import ASTRA_1KR_SYNTHETIC_TLE, earth_satellite, skyfield_ephemeris

if TYPE_CHECKING:
    from cssat.scene import Scenario


log = logging.getLogger("cssat")

#: the ``_target_`` of the scene target (``conf/target/scene.yaml``)
SCENE_TARGET = "cssat.experiments.scene.SceneTarget"


class SceneTarget:
    """A mesh in a scenario (the light-curve experiment's target): its settings are the ``model``,
    ``scenario``, ``render`` and ``shadows`` groups of the config, read by the scene forward model
    (``forward: scene``, :class:`~cssat.experiments.forward.scene.SceneLightCurve`)."""

    kind = "scene"


def read_observations(cfg: Any, check_only: bool = False) -> Any:
    """The measured light curve of ``cfg.observations`` (a path; ``None`` when unset), read with
    the ``observed`` settings (column names, kind, time format). Each ``observed`` key is first
    checked against :func:`cssat.data.read_light_curve`'s arguments: an unknown one (a typo,
    ``+observed.bogus=1``) is a FieldError naming ``observed.<key>`` and the allowed keys, not a
    TypeError's traceback; the reader's refusal of one of them names its key too
    (``observed.format``, ``observed.kind``). ``check_only``: the keys checked, nothing read
    (returns ``None``)."""
    import inspect  # local: read_light_curve's own parameters name the observed keys

    path = cfg.get("observations")
    if not path:
        return None
    from cssat.data import read_light_curve  # heavy: cssat.data imports torch

    kw = settings(cfg.get("observed"))
    allowed = [p for p in inspect.signature(read_light_curve).parameters if p != "path"]
    for k in kw:
        if k not in allowed:
            raise FieldError(f"observed.{k}", f"not an option of read_light_curve; the options: {', '.join(allowed)}")
    if check_only:
        return None
    try:
        return read_light_curve(str(path), **kw)
    except FieldError as err:  # an argument's error named by its config key: format -> observed.format
        head, _, tail = err.field.partition(".")
        arg = err.field if err.field in allowed else tail if head == "observations" and tail in kw else None
        if arg is None:
            raise
        raise FieldError(f"observed.{arg}", err.detail) from None


def check_elements(cfg: Any, lc: Any, max_epoch_days: float = 14.0) -> None:
    """Refuse an element set that is not the observed object's: ``scenario.tle`` (null: the
    synthetic Astra 1KR set) must carry the file's NORAD number when the file names one, and its
    epoch must lie within ``max_epoch_days`` of the observations (SGP4's error grows by
    kilometres a day). A FieldError naming ``scenario.tle``."""
    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    tle = cfg.scenario.get("tle")
    given = tle is not None
    tle = ASTRA_1KR_SYNTHETIC_TLE if tle is None else OmegaConf.to_container(tle) if OmegaConf.is_config(tle) else tle
    ts, _ = skyfield_ephemeris()
    sat, _ = earth_satellite(tle, ts)
    obj = str(lc.meta.get("object_id") or "").strip()
    satnum = int(sat.model.satnum)
    what = "scenario.tle" if given else "scenario.tle is null: the synthetic Astra 1KR set"
    if obj.isdigit() and int(obj) != satnum:
        raise FieldError("scenario.tle", f"the element set is of NORAD {satnum} ({what}), the observations of NORAD {obj}"
                                         f"{' ' + lc.meta['name'] if lc.meta.get('name') else ''}: give the object's own TLE")
    epoch = np.datetime64(sat.epoch.utc_datetime().replace(tzinfo=None), "us")
    days = float(np.abs((lc.times_utc[[0, -1]] - epoch) / np.timedelta64(1, "D")).max())
    if given and days > max_epoch_days:
        raise FieldError("scenario.tle", f"its epoch {epoch} is {days:.1f} days from the observations; SGP4 drifts by "
                                         f"kilometres a day: give an element set within {max_epoch_days:g} days")


def build_scenario(cfg: Any, times: Any = None, sites: Any = None) -> Scenario:
    """The :class:`cssat.scene.Scenario` of the ``scenario`` config (the synthetic Astra 1KR TLE
    when ``scenario.tle`` is null), on ``times`` (UTC) or ``scenario.times`` when given, else on
    its regular grid. ``sites (T, 3)`` (latitude °, longitude °, altitude m of each sample's
    observer, e.g. a SCORE file's): one observer per sample — each site's samples computed with
    its own observer, then put back in time order — instead of ``scenario.observer``."""
    if sites is not None and times is not None:
        sites = np.asarray(sites, dtype=np.float64)
        uniq, which = np.unique(sites, axis=0, return_inverse=True)
        which = which.reshape(-1)
        if len(uniq) > 1:
            stamps = np.asarray(times, dtype="datetime64[us]")
            parts = []
            for k, (lat, lon, alt) in enumerate(uniq):
                from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

                sub = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
                with open_dict(sub):
                    sub.scenario.observer = {"lat_deg": float(lat), "lon_deg": float(lon), "alt_m": float(alt)}
                parts.append((np.flatnonzero(which == k), build_scenario(sub, stamps[which == k])))
            arrays = {}
            for f in dataclasses.fields(parts[0][1]):
                if f.name == "name":
                    continue
                first = getattr(parts[0][1], f.name)
                out = np.empty((len(stamps),) + first.shape[1:], dtype=first.dtype)
                for idx, sc_k in parts:
                    out[idx] = getattr(sc_k, f.name)
                arrays[f.name] = out
            return dataclasses.replace(parts[0][1], **arrays)
        lat, lon, alt = uniq[0]
        from omegaconf import OmegaConf, open_dict  # heavy: omegaconf; library code, importable without Hydra

        cfg = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
        with open_dict(cfg):
            cfg.scenario.observer = {"lat_deg": float(lat), "lon_deg": float(lon), "alt_m": float(alt)}

    from omegaconf import OmegaConf  # heavy: omegaconf; library code, importable without Hydra

    sc = cfg.scenario
    tle = sc.get("tle")
    # two or three lines, a TLE text, or an OMM/GP record as a mapping of CCSDS keys
    tle = ASTRA_1KR_SYNTHETIC_TLE if tle is None else OmegaConf.to_container(tle) if OmegaConf.is_config(tle) else tle
    obs = sc.observer
    if times is None and sc.get("times") is not None:
        times = list(sc.times)
    return make_scenario(
        tle=tle, start_utc=str(sc.start_utc),
        n_steps=int_param(sc.n_steps, "scenario.n_steps", 1), step_s=float(sc.step_s),
        lat_deg=float(obs.lat_deg), lon_deg=float(obs.lon_deg), alt_m=float(obs.alt_m), name=sc.get("name"),
        times=times,
    )
