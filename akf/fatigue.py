"""``[output.fatigue]`` of ``akf estimate``: rainflow counting, Miner damage and damage-equivalent
ranges of the estimated stresses, chunk by chunk (:class:`core_akf.fatigue.FatigueAccumulator`),
written to ``fatigue.csv`` and drawn in ``fatigue.png``."""
from __future__ import annotations

import numpy as np

from core_akf.checks import AKFInputError
from core_akf.fatigue import FatigueAccumulator, SNCurve, check_youngs_modulus, stress_operator

#: seconds per year (365.25 days) for the damage per year
YEAR = 365.25 * 86400.0
#: the default slope and cycles of the damage-equivalent range
DEL_SLOPE, DEL_CYCLES = 3.0, 2e6


def fatigue_curve(section) -> SNCurve:
    """The S-N curve of an ``[output.fatigue]`` section (a detail category or points of one's own)."""
    gamma = 1.0 if section.gamma_mf is None else float(section.gamma_mf)
    if (section.detail_category is None) == (section.sn_curve is None):
        raise AKFInputError("[output.fatigue] needs the S-N curve: detail_category = 71 (EN 1993-1-9, MPa) or "
                            "sn_curve = [[N, range in MPa], ...], one of them")
    if section.detail_category is not None:
        return SNCurve.ec3(section.detail_category, gamma)
    return SNCurve.from_points(section.sn_curve, gamma)


def fatigue_outputs(structure, section) -> list[int]:
    """The strain outputs (0-based) an ``[output.fatigue]`` section assesses: ``outputs``,
    ``members`` or every strain output."""
    if section.outputs is not None and section.members is not None:
        raise AKFInputError("[output.fatigue] takes outputs (strain labels) or members (truss member numbers), not both")
    if section.members is not None:
        if structure.strain_kind != "member":
            raise AKFInputError("[output.fatigue] members are truss member numbers; this model's strain outputs are "
                                "at nodes: list them in outputs = [\"strain:40:ex\", ...]")
        labels = [f"strain:{m}" for m in section.members]
    elif section.outputs is not None:
        labels = list(section.outputs)
        others = [x for x in labels if not str(x).startswith("strain:")]
        if others:
            raise AKFInputError(f"fatigue is counted on strain outputs; [output.fatigue] outputs lists {others}, which "
                                "are not (an acceleration or another response has no stress): list strain outputs "
                                "such as \"strain:13\"")
    else:
        if not structure.n_strain:
            raise AKFInputError("[output.fatigue]: the model has no strain outputs to count fatigue on")
        return list(range(structure.n_strain))
    if len(set(labels)) != len(labels):
        raise AKFInputError(f"[output.fatigue] lists an output twice: {sorted({x for x in labels if labels.count(x) > 1})}")
    return structure.strain_label_index(labels)


class FatigueRun:
    """The fatigue of one ``akf estimate`` run: the estimated stresses of the chosen strain outputs
    counted chunk by chunk, and those of the truth for a simulated job."""

    def __init__(self, job, simulated):
        section = job.spec.output.fatigue
        structure = job.structure
        self.curve = fatigue_curve(section)
        self.index = fatigue_outputs(structure, section)
        self.labels = [structure.strain_labels[i] for i in self.index]
        if section.youngs_modulus is not None:
            check_youngs_modulus(section.youngs_modulus)
        self.W = stress_operator(structure, self.index, section.youngs_modulus)
        self.m = DEL_SLOPE if section.del_slope is None else float(section.del_slope)
        self.n_eq = DEL_CYCLES if section.del_cycles is None else float(section.del_cycles)
        k = len(self.index)
        self.estimated = FatigueAccumulator(k, self.curve, self.m, self.n_eq)
        self.reference = FatigueAccumulator(k, self.curve, self.m, self.n_eq) if simulated else None
        self.steps = 0

    def update(self, est, sim, step):
        """Count the chunk ``est`` (its first step is ``step`` of the record)."""
        n = est.forces.shape[0]
        if not n:
            return
        self.estimated.update(est.strains @ self.W.T)
        if self.reference is not None:
            self.reference.update(sim.strains[step:step + n] @ self.W.T)
        self.steps += n

    def merge(self, counts, steps):
        """Add the counts of the record's next piece, filtered elsewhere (a task of a time-parallel run).

        Parameters
        ----------
        counts : FatigueAccumulator
            The piece's estimated stresses counted (the same outputs and curve).
        steps : int
            The piece's steps.
        """
        self.estimated = counts if self.steps == 0 else self.estimated.merge(counts)
        self.steps += steps

    def frame(self, dt):
        """``fatigue.csv``: one row per output, each header with its unit (stress ranges in MPa, as
        the S-N curves; cycles; Miner's sum; per year at this record's rate)."""
        import pandas as pd

        s = self.estimated.summary()
        duration = self.steps * dt
        out = pd.DataFrame({"channel": self.labels, "cycles": s.cycles, "max_range_MPa": s.max_range / 1e6,
                            "damage": s.damage, "del_MPa": s.equivalent_range / 1e6,
                            "damage_per_year": s.damage * (YEAR / duration) if duration > 0 else np.nan})
        if self.reference is not None:
            r = self.reference.summary()
            out["damage_reference"] = r.damage
            out["del_reference_MPa"] = r.equivalent_range / 1e6
        return out

    def metrics(self, dt):
        """The JSON ``fatigue`` object: the curve, the settings, the rows of :meth:`frame` and the
        caveat of the yearly rate (:meth:`per_year_caveat`)."""
        return {"curve": self.curve.name, "del_slope": self.m, "del_cycles": self.n_eq,
                "units": {"max_range_MPa": "MPa", "del_MPa": "MPa", "damage": "Miner's sum",
                          "damage_per_year": "1/year"},
                "per_year": self.per_year_caveat(dt),
                "outputs": self.frame(dt).to_dict(orient="records")}

    def per_year_caveat(self, dt):
        """What ``damage_per_year`` assumes: the record's rate of damage held for a year (365.25 days)."""
        duration = self.steps * dt
        if duration <= 0:
            return "no record counted"
        text = (f"damage_per_year is the damage of {duration:.4g} s of record times {YEAR / duration:.3g}: it holds "
                "only if the record's loading is that of the whole year")
        return text + ("; a record shorter than a day rarely is" if duration < 86400 else "")

    def state(self):
        """The accumulators' state, for a checkpoint."""
        out = {f"est_{k}": v for k, v in self.estimated.state().items()} | {"fatigue_steps": np.array(self.steps)}
        if self.reference is not None:
            out |= {f"ref_{k}": v for k, v in self.reference.state().items()}
        return out

    def restore(self, saved):
        """Continue from a checkpoint's :meth:`state`."""
        try:
            self.estimated.restore({k[4:]: v for k, v in saved.items() if k.startswith("est_fatigue")})
            if self.reference is not None:
                self.reference.restore({k[4:]: v for k, v in saved.items() if k.startswith("ref_fatigue")})
            self.steps = int(saved["fatigue_steps"])
        except (KeyError, AKFInputError) as exc:
            from core_akf.filter import CheckpointError

            raise CheckpointError(f"the checkpoint lacks the fatigue counts ({exc}); start anew with --overwrite") from None
