"""The optics a training run may use, by name: trained height maps and fixed PSFs (the ``--doe`` and ``--psf``
choices). Kept apart from :mod:`hdrcam.train.optical_capture` so the command line can offer them without
importing torch."""

TRAINABLE_DOES = ("rank1", "freeform")
FIXED_PSFS = ("dirac", "star8", "dual-peak", "windshield")
