%
(arcs.nc: a full circle by I/J, arcs by R of both signs, quarter arcs by I/J,)
(and a half circle in G18, all within 150 mm in X/Y and 50 mm in Z of the origin)
G21 G90 G17 G94 G54
G64 P0.01
G0 Z5
(full circle: radius 30 mm about the origin, counter-clockwise)
G0 X30 Y0
G1 Z-1 F300
G3 X30 Y0 I-30 J0 F1000
G0 Z5
(R arcs on a 20 mm chord: R20 takes the 60 degree way, R-20 the 300 degree way)
G0 X-60 Y-40
G1 Z-1 F300
G2 X-40 Y-40 R20 F1000
G3 X-60 Y-40 R-20
G0 Z5
(quarter arcs by I/J about X60 Y40, clockwise)
G0 X60 Y60
G1 Z-1 F300
G2 X80 Y40 I0 J-20 F1000
G2 X60 Y20 I-20 J0
G0 Z5
(half circle in the ZX plane: a 10 mm radius bowl from X-10 to X10 through Z-10)
G18
G0 X-10 Y60
G1 Z0 F300
G2 X10 Z0 I10 K0 F800
G0 Z5
G17
G0 X0 Y0
M30
%
