%
(helix.nc: helical descent of five turns, radius 10 mm, 1 mm down per turn,)
(then one flat turn at the bottom, as a CAM helical ramp into a pocket does)
G21 G90 G17 G94 G54
G64 P0.01
G0 Z5
G0 X10 Y0
G1 Z0 F300
G3 X10 Y0 Z-1 I-10 J0 F800
G3 X10 Y0 Z-2 I-10 J0
G3 X10 Y0 Z-3 I-10 J0
G3 X10 Y0 Z-4 I-10 J0
G3 X10 Y0 Z-5 I-10 J0
G3 X10 Y0 I-10 J0
G1 X0 Y0
G0 Z5
M30
%
