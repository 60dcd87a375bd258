"""The layout of the bundled heads' texture atlas (``models/NAME-face.png``), in one place: the
model builder paints it (``models/src/texture.py``) and ``adi fit`` repaints it
(:mod:`vtts.fit.texture`).

Tiles are ``(u0, v0, u1, v1)`` in texture coordinates (v up): the skin of face, back of the head
and neck in the top three quarters, unwrapped around the skull's vertical axis
(``u = 0.5 ± (|θ|/π)^GAMMA / 2``), and four tiles below: eye, teeth, tongue, ear.
"""

#: The bundled atlas's side, in texels.
SIZE = 512
SKIN_TILE = (0.0, 0.25, 1.0, 1.0)
EYE_TILE = (0.0, 0.0, 0.25, 0.25)
TEETH_TILE = (0.25, 0.0, 0.5, 0.25)
TONGUE_TILE = (0.5, 0.0, 0.75, 0.25)
EAR_TILE = (0.75, 0.0, 1.0, 0.25)
#: Texels kept clear at a tile's edge so that filtering never reaches the neighbour.
INSET = 3 / SIZE
#: How much of the skin chart's width the front of the head gets (u = 0.5 ± (θ/π)^GAMMA / 2).
GAMMA = 0.6
