"""Multiple importance sampling weights (Veach 1997), shared by irradiance (Eq. 2) and shading."""

import drjit as dr


def power_heuristic(pdf_a, pdf_b):
    """``pdf_a^2 / (pdf_a^2 + pdf_b^2)``: the weight of a sample drawn with density ``pdf_a`` (0 where undefined)."""
    a2, b2 = pdf_a * pdf_a, pdf_b * pdf_b
    w = a2 / (a2 + b2)
    return dr.select(dr.isfinite(w), w, 0.0)
