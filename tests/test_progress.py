"""The progress bar's time left comes from the steps after the first.

The first step of a process compiles or loads the kernels and builds the first systems
(a first single-particle run: about 3 s of its 4.5 s); counted in the rate, the bar
predicted minutes for a run of seconds. A fake clock stands for the time.
"""

from tqdm import tqdm

from skfem_granular.simulation.progress import count_step


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_the_first_step_is_left_out_of_the_rate():
    clock = Clock()
    bar = tqdm(total=101, disable=False, mininterval=0, smoothing=0)
    bar._time = clock
    bar.reset()
    clock.now += 30.0  # the first step: kernels and first systems
    count_step(bar)
    for _ in range(10):  # then 0.5 s a step
        clock.now += 0.5
        count_step(bar)
    d = bar.format_dict
    bar.close()
    assert d["n"] == 11 and d["initial"] == 1
    assert d["elapsed"] == 5.0  # the clock started again after the first step
    rate = (d["n"] - d["initial"]) / d["elapsed"]
    assert rate == 2.0  # 90 steps left: 45 s, not (30 + 5) / 11 * 90 = 286 s


def test_a_hidden_bar_takes_the_steps():
    """A disabled tqdm has no ``initial``: the first step must not reach for it."""
    bar = tqdm(total=5, disable=True)
    for _ in range(3):
        count_step(bar)
    assert bar.n == 0  # a disabled bar does not count
    bar.close()
