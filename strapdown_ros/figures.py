"""
Figure output shared by the report tools.

A base module: matplotlib is imported only when a figure is saved.
"""
from __future__ import annotations

import os

from strapdown_ros.files import atomic_savefig

__all__ = ['save_figure']


def save_figure(fig, outdir: str, name: str) -> str:
    """
    Lay out, write and close a figure.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    outdir : str
        The output directory.
    name : str
        The file name (PNG, written at 110 dpi).

    Returns
    -------
    str
        The path written.

    """
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = os.path.join(outdir, name)
    atomic_savefig(fig, path, dpi=110)             # a temporary file, then os.replace
    plt.close(fig)
    return path
