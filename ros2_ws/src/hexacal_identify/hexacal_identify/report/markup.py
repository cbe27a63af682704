"""The HTML shell every report page shares: style, units, number formats and embedded figures."""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Iterable

from hexacal_msgs_py.models import ModelLayout
import numpy as np

UM, MM = 1e6, 1e3


def vector(values: Iterable[float | None]) -> np.ndarray:
    """Return ``values`` as floats (None entries as NaN)."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def vector_or_none(values: Iterable[float | None] | None) -> np.ndarray | None:
    """Return ``values`` as floats (None entries as NaN), or None without values."""
    if values is None:
        return None
    return vector(values)


def number_text(value, pattern: str) -> str:
    """Return ``value`` formatted by ``pattern``, or 'n/a' for None and non-finite values."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return 'n/a'
    return pattern.format(value)


def embedded_figure(out: Path, name: str, draw) -> str:
    """Return a <figure> with the PNG ``draw(out / name)`` writes, embedded as a data URI."""
    path = draw(out / name)
    encoded = base64.b64encode(Path(path).read_bytes()).decode('ascii')
    return (
        f'<figure><img src="data:image/png;base64,{encoded}" alt="{html.escape(name)}">'
        f'<figcaption>{html.escape(name)}</figcaption></figure>'
    )


_STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1150px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table.summary th { text-align: left; padding-right: 2em; font-weight: normal; color: #555; }
table.data { border-collapse: collapse; font-size: 0.85em; }
table.data td, table.data th { padding: 1px 8px; }
figure { margin: 1em 0; } img { max-width: 100%; } figcaption { font-size: 0.8em; color: #777; }
.verdict { font-weight: bold; white-space: pre-wrap; } .note { color: #777; }
"""

# Counts the images that decoded once the page has loaded, for headless checks (works offline: no
# requests).
_IMAGE_CHECK = """
window.addEventListener('load', function () {
  var images = document.images, loaded = 0;
  for (var i = 0; i < images.length; i++) {
    if (images[i].complete && images[i].naturalWidth > 0) loaded++;
  }
  document.body.setAttribute('data-images-loaded', String(loaded));
  document.body.setAttribute('data-images-total', String(images.length));
});
"""


def dimensionless_fields(layout: ModelLayout) -> list[str]:
    """
    Return the per-chain fields without a unit.

    Per-chain fields without a unit (the Hexa Slide's rail components ax, ay): shown as 1000 x the
    value.
    """
    return [name for name, unit in zip(layout.fields, layout.field_units) if unit == '1']


def page(title: str, sections: list[str], layout: ModelLayout) -> str:
    """Return the whole HTML page: title, units note, ``sections``, the image check."""
    dimensionless = dimensionless_fields(layout)
    scaled = (
        f' (dimensionless {", ".join(dimensionless)} as 1000 x the value)' if dimensionless else ''
    )
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f'<title>{html.escape(title)}</title><style>{_STYLE}</style></head>\n<body>'
        f'<h1>{html.escape(title)}</h1>'
        f"<p class='note'>Units: parameters in mm{scaled}, standard deviations "
        'and residuals in um and urad; the files hold SI units.</p>\n'
        + '\n'.join(sections)
        + f'\n<script>{_IMAGE_CHECK}</script></body></html>\n'
    )
