"""``labid.cli.main`` decides the threads early (before numpy loads) unless the command line
gives ``--threads``: ``threads_given`` must say so exactly when argparse reads a
``--threads`` value (issue 29 review: any word starting with "--t" skipped it, so
``acquire --total`` or ``--truth`` lost the early decision)."""
from __future__ import annotations

import pytest

from labid.cli.main import build_parser, threads_given

ACQUIRE = ["acquire", "--specimen", "cfrp", "--out", "run.h5"]
MODES = ["modes", "cfrp"]


@pytest.mark.parametrize("argv", [
    ACQUIRE, ACQUIRE + ["--total"], ACQUIRE + ["--truth", "0.7"], ACQUIRE + ["--truth=0.7"],
    ACQUIRE + ["--threads", "1"], ACQUIRE + ["--threads=1"], ACQUIRE + ["--thr", "1"], ACQUIRE + ["--th=1"],
    ACQUIRE + ["--total", "--thread", "1"],
    MODES, MODES + ["--t", "1"], MODES + ["--t=1"], MODES + ["--n", "3", "--threa", "1"],
    ["modes", "--", "--thr"],                   # after "--" a word is positional: the specimen's name
])
def test_threads_given_exactly_when_argparse_reads_threads(argv):
    parsed = build_parser(argv[0]).parse_args(argv)
    assert threads_given(argv) == (parsed.threads is not None), (argv, parsed.threads)


def test_words_that_only_start_like_it_are_not_threads():
    assert not threads_given(["plan", "cfrp", "--target-u", "1%"])
    assert not threads_given(["acquire", "--out", "--threads.h5"])   # no prefix of --threads
    assert not threads_given(["x", "--", "--threads", "2"])
