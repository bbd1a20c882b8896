"""The categories of the mOSD frames (../shared/data/README.md): learn0-16 boxes, 17-24 stacked
boxes, 25-32 occluded objects, 33-44 cylindric objects; of the test frames in mosd-clutter,
test43 and the even numbers are mixed scenes, the odd numbers from 55 complex piles."""
import re

CATEGORIES = ('boxes', 'stacked', 'occluded', 'cylindric', 'mixed', 'complex')


def category(frame):
    """The category of an mOSD frame name (learnN or testN)."""
    m = re.match(r'learn(\d+)', frame)
    if m:
        k = int(m.group(1))
        return 'boxes' if k <= 16 else 'stacked' if k <= 24 else 'occluded' if k <= 32 else 'cylindric'
    k = int(re.match(r'test(\d+)', frame).group(1))
    return 'mixed' if k == 43 or k % 2 == 0 else 'complex'
