"""The dense analysis's thresholds and constants, each with where it comes from."""

from __future__ import annotations

REGISTRATION_BLUR_PX = 1.0  # both images smoothed alike before the flow (as the tiles are)
NORM_SIGMA_PX = 6.0  # window of the local exposure normalisation before the flow
TENSOR_SIGMA_PX = 3.0  # window of the structure tensor
# structure-tensor eigenvalue (grey levels² per px², in the photo's contrast at its resolution)
# where the dense flow is the pixel's own: DIS fills weakly textured areas from their
# neighbours (its smoothness term), so below this the flow there is theirs, however low the
# noise (measured: a 1 mm bubble's flow spread 3 mm into plain paper below it). It is about
# an edge of 10 grey levels' contrast, the least a designer draws on purpose.
MIN_EDGE = 4.0
MIN_TWO_WAY = 4.0  # the same for the smaller eigenvalue: the full vector
# the share of a slide the window's slide (about a millimetre, below) answers, as the detection limit
# states it: measured on the corpus's slid discs (bubbles of 4 to 12 mm, the window's slide inside
# the inner 70 % of each against the truth), where the window's texture has two directions within a
# factor of 10, 0.67 to 0.96 on the workbench renderer at 3000 x 2250 (7 of 8 bubbles; 0.40 on the
# eighth) and 0.71 to 0.80 on Mitsuba at 2000 x 1500 (5 of 7; 0.25 and 3.4 on the others), median
# 0.75 of the 15. Where its directions are 20 to 84 times apart (a soft edge that turns by a few
# degrees over the window) it answered -0.06, 0.05 and 0.42 (3 bubbles): WINDOW_GAIN_ALONG_EDGE,
# their median, below WINDOW_TWO_WAY_STATED. With the noise alone the limit stated bubbles found
# that the window answered at two thirds of their slide or less, and three escaped at 3000 x 2250
# (corpus of 2026-12-04)
WINDOW_GAIN = 0.75
WINDOW_GAIN_ALONG_EDGE = 0.05
WINDOW_TWO_WAY_STATED = 0.1  # the window's weaker eigenvalue over its stronger
# a defect is significant when the misregistration (or colour residual) exceeds the tolerance
# by more than this many of its standard uncertainties: one-sided 0.13 % per pixel, so a perfect
# photo's chance exceedances are single pixels, which the defects' opening removes
SIGNIFICANCE_Z = 3.0
# the stated limit is what is found with 95 % probability: a defect exactly at the significance
# threshold is found half the time, one 1.645 standard uncertainties beyond it 95 % of the time
DETECT_Z = 1.645
# the least noise assumed, grey levels: 8-bit quantisation of the photo and of the print
# (0.29 each) and their resampling through the warp
NOISE_FLOOR = 0.5
# the gain a pixel may have of its own beyond the exposure fit: shading within a crease (seen
# on the face mask: 0.63 of the fitted brightness over 8 mm² under the jaw)
SHADING = 1.6
# the dense flow's own accuracy floor, grid px: DIS (medium preset) on locally normalised
# 8-bit images errs by 0.02 to 0.04 px RMS on band-limited textures however low the noise
# (measured in tests/test_uncertainty.py: 0.040 px for features 1.5 px across, 0.019 px for
# 3 px, at noise 1, where the least-squares bound is 0.005 px); the larger is taken
FLOW_FLOOR_PX = 0.04
# the flow's floor in the photo's own pixels: its sampling, interpolation, demosaicing, JPEG and
# the renderer's or lens's pixel-level detail move an edge by a fraction of a photo pixel that no
# window averages away (its errors are correlated over the flow's window). Measured on perfect
# photos, per component: 0.12 to 0.18 photo px at 12 Mpx (a 1.2 photo px per grid px) and 0.17
# to 0.25 where a 2000 x 1500 photo sees a face mask's flank at 0.25 photo px per grid px, where
# the grid-pixel floor alone predicted a third of that
PHOTO_FLOOR_PX = 0.15
UNRESOLVED_KEEP = 0.25  # share of the print's gradient energy a photo must keep to resolve its detail
EXPOSURE_SIGMA_PX = 40.0  # window of the local gain/offset fit: larger than any defect it must not absorb
COLOUR_TOL = 40.0  # grey levels (0-255) beyond the exposure model that make a colour defect
SATURATED = 250  # a channel this bright is clipped (its colour is not known)
# a glint along a thin line over textured ink keeps the ink's texture (thin_told; measured:
# correlation 0.85 to 0.97 between the photo and the design in highlights on checkers); bare film
# shows none of it
KEPT_TEXTURE = 0.6
# ... at a contrast of at least this share of the design's (a highlight near clipping compresses it:
# 0.57 to 1.1 measured)
KEPT_CONTRAST = 0.4
# the film's colour is taken where the design is this near it in every channel (a short
# extrapolation of the exposure fit), from at least this many pixels (a median of chromaticity
# settles to a grey level within a few hundred; fewer leave the fit's own white)
FILM_NEAR = 0.75
MIN_FILM_PX = 500
MAX_FILM_SAMPLES = 100_000
MIN_CORE_PX = 10  # a thin line is told light or ink on its core where it holds this many pixels (thin_told)
# a fold: the surface's normal turned this far from its mean over 0.75 mm (half the fold's
# dihedral angle; smooth curvature turns it under a degree there): light along it is told from ink by
# nothing in one photo (along_fold)
CREASE_DEG = 10.0
# a shift defect's flow must take away this share of the residual over its region (measured: bubbles
# of 4 to 12 mm on their renders 0.76 to 0.92, the flow over faint dark texture on a perfect part 0.61)
SHIFT_EXPLAINS = 2.0 / 3.0
# texture lost: a local gain below LOST_GAIN of the photo's median where the design's contrast in the
# exposure window is at least LOST_MIN_CONTRAST grey levels (its standard deviation), and below
# LOST_GAIN of the light that is there (the photo's local mean over the design's): a shadow dims the
# design's contrast with its mean, paint over it takes the contrast and leaves its own mean (a
# Mitsuba photo of the lion's top: a fold at a third of the photo's light, its lilac-to-green edge
# at gain 0.3 of the photo's and 1 of its own light, was a 5.8 mm² "colour" defect)
LOST_GAIN = 0.3
# a colour region whose mean reflected ray lies within this of a sure highlight's faces the same lamp
# (measured: highlights on flat pale ink 0.6 to 3.7 deg from the photo's clipped or texture-keeping
# ones; dropouts 16 to 103 deg)
MIRROR_DEG = 8.0
# photos see one print point from directions no one lamp serves both when their cameras, seen
# from it, lie more than twice the lamp's reach apart (reflection keeps the angle between rays)
APART_DEG = 2.0 * MIRROR_DEG
LOST_MIN_CONTRAST = 15.0
SHADOW = 35.0  # the film's white predicted darker than this is a deep shadow
MIN_DEFECT_MM2 = 1.0  # smaller regions are noise, not defects
SHIFT_CLOSE_MM = 1.0  # gaps between textured parts of a shifted region that are closed when sizing it
MISSING_GAP_MM = 1.5  # pieces of ink gone this close are one defect (see find_defects)
MIN_SHIFT_WINDOWS = 2.0  # independent flow windows of evidence a shift defect needs (see find_defects)

# the flow's grid and the median the colour's model follows (flow.py)
FLOW_RESOLUTION = 0.75  # below this many photo px per grid px the flow runs at the photo's resolution
MEDIAN_FLOW_MM = 2.0  # the window of the flow's median the colour's model follows

# the photo's local blur (blur.py)
BLUR_LEVELS = (0.0, 0.75, 1.0, 1.5, 2.0, 3.0, 4.5, 6.0)  # grid px: the blurs a local PSF is rounded to
PRINT_BLUR_PX = 0.5  # the print's own blur, grid px: see blur.PhotoBlur

# the regions taken for light that validation.json lists (light.py)
MAX_NOT_COUNTED = 50  # regions listed at most (the largest); all of them are in the coverage map as highlight

# scratches: thin lines of ink gone (lines.py)
SCRATCH_MM = 1.5  # ink gone along a line narrower than about half this is a scratch (thin_ink_loss)
# the thin test's noise is also taken per block of this many grid px (thin_ink_loss): as wide as
# the exposure fit's window (EXPOSURE_SIGMA_PX), where the light and the photo's sampling change
# little, and about 25 times a scratch's width, so that a scratch is a small share of its blocks
NOISE_BLOCK_PX = 40
# the scratch the detection map states: a line of ink gone this wide on the print (print mm), the
# corpus's scratches (20 x 0.5 mm); a wider one steps further towards the film through the same
# blur, so it is found wherever this one is
SCRATCH_WIDTH_MM = 0.5
# a scratch's line is judged without the broad colour tolerance only where the film is stretched
# less than this (surface mm per print mm): beyond, a thin line of print is broad on the part
THIN_MAX_STRETCH = 2.0
