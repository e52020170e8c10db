%
(square.nc: a 40 mm square with sharp corners, centred on the work origin)
(G61: exact path, no corner is blended, so the planner must come to rest at each one)
G21 G90 G17 G94 G54
G61
G0 Z5
G0 X-20 Y-20
G1 Z-1 F300
G1 X20 F1200
Y20
X-20
Y-20
G0 Z5
G0 X0 Y0
M30
%
