"""Helpers shared by the test files."""

from __future__ import annotations


def assert_png(path: str, min_pixels: int = 200) -> None:
    """A real figure: a PNG that decodes, of a plausible size, not one flat colour."""
    import matplotlib.image

    img = matplotlib.image.imread(path)
    assert img.ndim == 3 and min(img.shape[:2]) >= min_pixels, (path, img.shape)
    assert float(img[..., :3].std()) > 0.01, f"{path} is blank"
