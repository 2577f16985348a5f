"""
Figures placed inside the Markdown of the reproduction reports.

A report section sets the paper's table or figure beside ours; its figures belong right after
the table they illustrate, not at the end of the report.  :func:`place_figures` inserts the
image links there, by the heading each figure belongs to (:data:`FIGURE_PLACES`).  Used by
``reproduce_seeds`` and by the per-paper pages of :mod:`.vavilov1982` and :mod:`.vasilyuk2024`.
No ROS imports.
"""
from __future__ import annotations

import os
import re

#: each figure's heading: the figure goes right after the first table under that heading, or at
#: the end of that subsection when it has no table
FIGURE_PLACES = {
    'seeds_000_errors.png': '### quantized_centred',
    'seeds_000_ablations.png': "### What makes the paper's",
    'seeds_000_centring.png': '### Quantized, Monte Carlo',
    'seeds_001_measures.png': '### Aircraft',
    'seeds_001_filter.png': '### Stationary filters',
    'seeds_004_sigma.png': '## 004 — boresight σ pattern',
    'seeds_004_theta_diff.png': '### 004 Fig. 3',
    'seeds_004_fig2.png': '### 004 Fig. 2',
    'seeds_004_ablation.png': '### 004 §6 — why',
}


def _insertion_index(lines: list[str], heading: str) -> int:
    start = next((i for i, line in enumerate(lines) if line.startswith(heading)), None)
    if start is None:
        return len(lines)
    i = start + 1
    while i < len(lines) and not lines[i].startswith('#'):
        if lines[i].startswith('|'):
            while i < len(lines) and lines[i].startswith('|'):
                i += 1
            return i
        i += 1
    return i


def place_figures(text: str, paths: list[str], base: str = '.') -> str:
    """
    Insert image links into a report section, each right after the table it illustrates.

    Parameters
    ----------
    text : str
        Markdown of one report section (or a page of several).
    paths : list of str
        PNG files of that section; a file not in :data:`FIGURE_PLACES` (or whose heading is
        absent) goes at the end of the text.
    base : str
        Directory the links are relative to (the report's directory).

    Returns
    -------
    str
        The Markdown with a line ``![name](relative path)`` per figure.

    """
    lines = text.split('\n')
    for path in paths:
        name = os.path.basename(path)
        link = f'![{name}]({os.path.relpath(os.path.abspath(path), base)})'
        i = _insertion_index(lines, FIGURE_PLACES.get(name, '\0'))
        lines[i:i] = ['', link, '']
    return re.sub(r'\n{3,}', '\n\n', '\n'.join(lines))
