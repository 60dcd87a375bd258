"""Fitting a personalized head to a photograph (``adi fit``).

>>> from vtts.fit import fit_photo, load_photo
>>> image, focal = load_photo("me.jpg")
>>> head = fit_photo(image, focal_35mm=focal)
>>> head.write("me.wrl")                      # me.wrl, me.adt, me-face.png

Stages (plain values between them): :mod:`~vtts.fit.landmarks` (the face detector),
:mod:`~vtts.fit.generic` (the generic head as Candide control points),
:mod:`~vtts.fit.shape` (pose, camera, shape), :mod:`~vtts.fit.head` (the whole head and its
tables), :mod:`~vtts.fit.texture` (the photo as the skin), :mod:`~vtts.fit.frame` (a video's first
frame as the texture of the head made for that video), :mod:`~vtts.fit.report`.
"""

from vtts.fit.photo import FittedHead, fit_photo, load_photo, with_frame

__all__ = ["FittedHead", "fit_photo", "load_photo", "with_frame"]
