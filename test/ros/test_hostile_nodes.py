"""
The fuzz test of issue 27 over the nodes: one hostile message in an otherwise clean stream.

attitude_filter_node, calibrator_node and sins_node, each in-process in its own namespace (the
session's ROS domain is its own: test/conftest.py), get a short simulated recording through
their callbacks — gyro messages as the bytes of their raw subscriptions — clean and then with one
hostile message of a kind drawn from :data:`strapdown_ros.bench.hostile_input.KINDS`.  An
exception out of a callback (what would make the node exit) fails; so does a message not
counted under its named reason, or an estimate beyond 1σ of the clean run
(:func:`strapdown_ros.bench.hostile_tools.problems`).  Hypothesis draws a bounded sample with a
fixed seed; ``hostile_bench`` runs them all.
"""
import numpy as np
import pytest

hypothesis = pytest.importorskip('hypothesis')
st = pytest.importorskip('hypothesis.strategies')

from strapdown_ros.bench.hostile_input import (BETA, BIAS, clean_recording, KINDS,  # noqa: E402
                                               streams_with)
from strapdown_ros.bench.hostile_tools import problems  # noqa: E402
from strapdown_ros.bench.ros.hostile_nodes import fed_to_nodes, NODES, run_node  # noqa: E402

CASES = st.tuples(st.sampled_from(KINDS), st.integers(0, 10**6),
                  st.sampled_from(NODES)).filter(lambda c: fed_to_nodes(c[0], c[2]))


@pytest.fixture(scope='module')
def clean(ros):
    """Give the clean recording and every node's run on it."""
    rec = clean_recording()
    return rec, {n: run_node(n, rec) for n in NODES}


def test_every_node_takes_the_clean_recording_and_finds_the_truth(clean):
    _, runs = clean
    for n, o in runs.items():
        assert o.traceback is None, (n, o.traceback)
    cal, flt = runs['calibrator_node'], runs['attitude_filter_node']
    assert np.all(np.abs(cal.estimate - BETA) < 3 * cal.sigma), (cal.estimate, cal.sigma)
    assert np.all(np.abs(flt.estimate - BIAS) < 3 * flt.sigma), (flt.estimate, flt.sigma)


@hypothesis.seed(27)
@hypothesis.settings(max_examples=24, deadline=None, database=None,
                     suppress_health_check=list(hypothesis.HealthCheck))
@hypothesis.given(case=CASES)
def test_one_hostile_message_is_counted_and_costs_nothing_else(clean, case):
    kind, where, node = case
    rec, runs = clean
    n = len(rec.gyro if kind.stream == 'gyro' else rec.reference)
    got = run_node(node, streams_with(rec, kind, where % n, frames_used=False))
    assert problems(kind, runs[node], got) == []
