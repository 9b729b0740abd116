# Writes cie1931_d65.tsv, the CIE 1931 2-degree observer and the D65 illuminant at 1 nm over 360-830 nm, from the
# CIE's published tables as colour-science carries them (pip install colour-science; run once, the output is kept
# in the repository). D65 is tabulated to 780 nm there (CIE 15:2004 Table T.1, 5 nm, linearly interpolated to 1 nm
# as the CIE prescribes); above 780 nm it follows the D-series formula with D65's M1 and M2 (CIE 15:2004 eq. 3.5),
# which reproduces the tabulated values to the table's rounding.
import colour
import numpy as np

cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
d65 = colour.SDS_ILLUMINANTS["D65"]
basis = colour.colorimetry.datasets.illuminants.SDS_BASIS_FUNCTIONS_CIE_ILLUMINANT_D_SERIES
m1, m2 = -0.2952, -0.6848  # D65's, rounded to the precision CIE 15 uses for the tabulated illuminant


def d65_at(nm):
    if nm <= 780:
        lo = 5 * (nm // 5)
        hi = min(lo + 5, 780)
        t = (nm - lo) / 5.0
        return (1 - t) * d65[lo] + t * d65[hi] if hi != lo else d65[lo]
    return basis["S0"][nm] + m1 * basis["S1"][nm] + m2 * basis["S2"][nm]


with open("cie1931_d65.tsv", "w") as out:
    out.write("# nm\txbar\tybar\tzbar\td65 (CIE 1931 2-degree observer; D65 relative SPD, 100 at 560 nm)\n")
    for nm in range(360, 831):
        x, y, z = cmfs[nm]
        out.write(f"{nm}\t{x:.9g}\t{y:.9g}\t{z:.9g}\t{d65_at(nm):.6f}\n")
