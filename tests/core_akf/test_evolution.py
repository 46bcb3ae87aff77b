"""The one GA engine (core_akf.evolution): DEAP-equivalent operators on a private random stream,
Python's global ``random`` left alone, JSON checkpoints, and the same run whatever else draws
random numbers meanwhile (a dask client, a user's code)."""
import json
import random

import numpy as np
import pytest

from core_akf.evolution import (
    Algorithm,
    Evaluator,
    GeneticAlgorithm,
    Individual,
    best,
    blend,
    gaussian,
    load_checkpoint,
    tournament,
)


def _population(values):
    return [Individual([i], (v,)) for i, v in enumerate(values)]


@pytest.mark.parametrize("seed", range(5))
def test_operators_draw_like_deap_on_a_private_stream(seed):
    from deap import tools

    values = np.random.default_rng(seed).integers(0, 5, 12).astype(float)   # with ties
    pop = _population(values)
    random.seed(seed)
    expected = [i[0] for i in tools.selTournament(pop, 9, tournsize=3)]
    got = [i[0] for i in tournament(pop, 9, 3, random.Random(seed))]
    assert got == expected
    assert [i[0] for i in best(pop, 4)] == [i[0] for i in tools.selBest(pop, 4)]
    a, b = [0.1, 2.0, -1.0], [1.5, -0.5, 3.0]
    random.seed(seed)
    ea, eb = tools.cxBlend(list(a), list(b), 0.3)
    em, = tools.mutGaussian(list(a), 0.0, 0.4, 0.5)
    pyrng = random.Random(seed)
    assert blend(list(a), list(b), 0.3, pyrng) == (ea, eb)
    assert gaussian(list(a), 0.4, 0.5, pyrng) == em


class _Sphere(Algorithm):
    """Minimise sum((x - 1)^2) on 3 genes: elitist, tournament, blend + Gaussian."""

    def initial(self, rng, pyrng):
        return [rng.uniform(-3, 3, 3).tolist() for _ in range(12)]

    def next_generation(self, pop, gen, rng, pyrng, evaluate):
        kids = [i.copy() for i in tournament(pop, 11, 3, pyrng)]
        for a, b in zip(kids[::2], kids[1::2]):
            blend(a, b, 0.3, pyrng)
            del a.fitness.values, b.fitness.values
        for k in kids:
            if rng.random() < 0.5:
                gaussian(k, 0.3, 0.5, pyrng)
                del k.fitness.values
        return [best(pop, 1)[0].copy()] + kids


def _sphere(xs):
    return [float(np.sum((np.asarray(x) - 1.0) ** 2)) for x in xs]


def _noisy_sphere(xs):
    random.random()                  # someone else drawing from the global stream (a dask client)
    return _sphere(xs)


def _run(fn=_sphere, **kw):
    return GeneticAlgorithm(_Sphere(), Evaluator(fn, batch=4), generations=12, seed=7, **kw).run()


def test_global_random_state_is_neither_used_nor_changed():
    random.seed(123)
    before = random.getstate()
    res = _run()
    assert random.getstate() == before
    other = _run(_noisy_sphere)           # global draws in between change nothing
    assert res.logbook.drop(columns="seconds").equals(other.logbook.drop(columns="seconds"))
    assert res.hall_of_fame == other.hall_of_fame
    assert res.hall_of_fame[0][1][0] < 0.05 and res.logbook["best"].is_monotonic_decreasing


def test_checkpoint_is_json_and_resume_repeats_the_run(tmp_path):
    ck = tmp_path / "ga.json"
    whole = _run(checkpoint=str(tmp_path / "whole.json"), checkpoint_every=4)
    partial = GeneticAlgorithm(_Sphere(), Evaluator(_sphere, batch=4), generations=12, seed=7,
                               checkpoint=str(ck), checkpoint_every=4)
    partial.generations = 5                  # stop early: the checkpoint holds generation 4 (and 5)
    partial.settings["generations"] = 12
    partial.run()
    data = json.loads(ck.read_text())        # plain JSON: loading it runs no code
    assert data["generation"] == 5 and data["format"][0] == "akf-toolkit GA checkpoint"
    resumed = GeneticAlgorithm(_Sphere(), Evaluator(_sphere, batch=4), generations=12, seed=7,
                               checkpoint=str(ck), resume=True).run()
    assert resumed.logbook.drop(columns="seconds").equals(whole.logbook.drop(columns="seconds"))
    assert resumed.hall_of_fame == whole.hall_of_fame
    (tmp_path / "bad.json").write_text('{"format": ["something else", 1]}')
    with pytest.raises(ValueError, match="not a GA checkpoint of this version"):
        load_checkpoint(str(tmp_path / "bad.json"))


def test_batches_are_fixed_whatever_the_workers():
    one = _run()
    two = GeneticAlgorithm(_Sphere(), Evaluator(_sphere, batch=4, n_jobs=2), generations=12, seed=7).run()
    assert one.hall_of_fame == two.hall_of_fame
    assert one.logbook.drop(columns="seconds").equals(two.logbook.drop(columns="seconds"))
