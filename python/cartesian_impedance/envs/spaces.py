"""Box: a space of real vectors between bounds, with the API of gymnasium.spaces.Box.

Gymnasium is not required. Where it is importable, `Box` IS gymnasium.spaces.Box, so the
environments' spaces pass Gymnasium's own checks; otherwise this module's `Box` stands in with the
same attributes and the same random streams (a PCG64 Generator seeded from a SeedSequence, as
gymnasium.utils.seeding.np_random makes it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["Box", "GYMNASIUM_AVAILABLE", "np_random"]


def np_random(seed=None):
    """(Generator, seed) as gymnasium.utils.seeding.np_random returns them: a PCG64 generator
    from np.random.SeedSequence(seed), and the entropy it was seeded with. `seed` must be None or
    a non-negative int."""
    if seed is not None and not (isinstance(seed, (int, np.integer)) and not
                                 isinstance(seed, bool) and seed >= 0):
        raise ValueError("seed = %r must be None or a non-negative int" % (seed,))
    sequence = np.random.SeedSequence(None if seed is None else int(seed))
    return np.random.Generator(np.random.PCG64(sequence)), sequence.entropy


class _Box:
    """A (possibly unbounded) box in R^n: every x with low <= x <= high elementwise.

    Box(low, high, shape=None, dtype=np.float32, seed=None): low and high are scalars or arrays of
    `shape` (taken from them when not given). Attributes low, high, shape, dtype, np_random;
    seed(seed) -> [seed], sample() (uniform where bounded on both sides, exponential where
    bounded on one, normal where unbounded, as Gymnasium samples), contains(x) / `x in box`,
    is_bounded(manner)."""

    def __init__(self, low, high, shape=None, dtype=np.float32, seed=None):
        self.dtype = np.dtype(dtype)
        if not np.issubdtype(self.dtype, np.floating):
            raise ValueError("Box dtype = %s: only floating-point boxes are provided without "
                             "Gymnasium" % self.dtype)
        if shape is None:
            for bound in (low, high):
                if np.ndim(bound) > 0:
                    shape = np.shape(bound)
                    break
            else:
                raise ValueError("Box: shape must be given when low and high are scalars")
        self._shape = tuple(int(n) for n in shape)
        self.low = np.full(self._shape, low, dtype=self.dtype) if np.ndim(low) == 0 else \
            np.asarray(low, dtype=self.dtype)
        self.high = np.full(self._shape, high, dtype=self.dtype) if np.ndim(high) == 0 else \
            np.asarray(high, dtype=self.dtype)
        for name, bound in (("low", self.low), ("high", self.high)):
            if bound.shape != self._shape:
                raise ValueError("Box: %s has shape %s, expected %s" %
                                 (name, bound.shape, self._shape))
            if np.any(np.isnan(bound)):
                raise ValueError("Box: %s contains NaN" % name)
        if np.any(self.low > self.high):
            raise ValueError("Box: low > high at index %d" %
                             int(np.argmax(self.low > self.high)))
        self.bounded_below = -np.inf < self.low
        self.bounded_above = np.inf > self.high
        self._np_random = None
        if seed is not None:
            self.seed(seed)

    @property
    def shape(self):
        return self._shape

    @property
    def np_random(self) -> np.random.Generator:
        """The generator sample() draws from (seeded from fresh entropy on first use)."""
        if self._np_random is None:
            self.seed()
        assert self._np_random is not None
        return self._np_random

    def seed(self, seed=None):
        """Seeds np_random; returns [the seed] (the entropy used when seed is None)."""
        self._np_random, used = np_random(seed)
        return [used]

    def is_bounded(self, manner="both") -> bool:
        below = bool(np.all(self.bounded_below))
        above = bool(np.all(self.bounded_above))
        if manner == "both":
            return below and above
        if manner == "below":
            return below
        if manner == "above":
            return above
        raise ValueError("manner = %r is not one of 'both', 'below', 'above'" % (manner,))

    def sample(self, mask=None):
        if mask is not None:
            raise ValueError("Box.sample: masks are not supported for Box spaces")
        sample = np.empty(self._shape, dtype=np.float64)
        both = self.bounded_below & self.bounded_above
        below = self.bounded_below & ~self.bounded_above
        above = ~self.bounded_below & self.bounded_above
        neither = ~self.bounded_below & ~self.bounded_above
        rng = self.np_random
        sample[neither] = rng.normal(size=neither[neither].shape)
        sample[below] = rng.exponential(size=below[below].shape) + self.low[below]
        sample[above] = -rng.exponential(size=above[above].shape) + self.high[above]
        sample[both] = rng.uniform(low=self.low[both], high=self.high[both],
                                   size=both[both].shape)
        return sample.astype(self.dtype)

    def contains(self, x) -> bool:
        if not isinstance(x, np.ndarray):
            try:
                x = np.asarray(x, dtype=self.dtype)
            except (ValueError, TypeError):
                return False
        return bool(np.can_cast(x.dtype, self.dtype) and x.shape == self._shape and
                    np.all(x >= self.low) and np.all(x <= self.high))

    def __contains__(self, x) -> bool:
        return self.contains(x)

    def __eq__(self, other) -> bool:
        # As Gymnasium's: the dtype is not compared, the bounds with np.allclose.
        return (isinstance(other, _Box) and self._shape == other._shape and
                bool(np.allclose(self.low, other.low)) and
                bool(np.allclose(self.high, other.high)))

    def __repr__(self) -> str:
        return "Box(%s, %s, %s, %s)" % (self.low.min(), self.high.max(), self._shape,
                                         self.dtype)


try:
    import gymnasium as _gymnasium
    from gymnasium.spaces import Box  # noqa: F401  (the real one where it is installed)
    GYMNASIUM_AVAILABLE = True
except ImportError:
    _gymnasium = None
    Box = _Box
    GYMNASIUM_AVAILABLE = False
