%
(pocket.nc -- a rounded pocket and an outside contour, for csgnb's milling simulation)
(stock: 50 x 40 x 10 mm, origin at the lower left corner of the top face, z = 0 on top)
(tool: T1, 6 mm flat end mill; run: python -m csgnb.mill csgnb/apps/examples/pocket.nc --stock 50 40 10 --tool flat:6)
(pocket: 24 x 16 mm, corner radius 5, 4 mm deep in two 2 mm steps; tool centre paths below)
N10 G21 G90 G17 G94 G40 G49
N20 T1 M6
N30 S10000 M3
N40 G0 Z5
N50 G0 X25 Y20

(level 1: plunge in the middle, clear outwards, finish along the rounded wall)
N100 G1 Z-2 F150
N110 G1 X21 F600
N120 G1 X29
N130 G1 X30 Y17
N140 G1 X20
N150 G1 Y23
N160 G1 X30
N170 G1 Y17
N180 G1 X32 Y15
N190 G1 X18 Y15 F500
N200 G2 X16 Y17 I0 J2
N210 G1 Y23
N220 G2 X18 Y25 I2 J0
N230 G1 X32
N240 G2 X34 Y23 I0 J-2
N250 G1 Y17
N260 G2 X32 Y15 I-2 J0
N270 G1 X25 Y20 F600

(level 2: the same 2 mm lower)
N300 G1 Z-4 F150
N310 G1 X21 F600
N320 G1 X29
N330 G1 X30 Y17
N340 G1 X20
N350 G1 Y23
N360 G1 X30
N370 G1 Y17
N380 G1 X32 Y15
N390 G1 X18 Y15 F500
N400 G2 X16 Y17 R2
N410 G1 Y23
N420 G2 X18 Y25 R2
N430 G1 X32
N440 G2 X34 Y23 R2
N450 G1 Y17
N460 G2 X32 Y15 R2
N470 G0 Z5

(outside contour: a 44 x 34 part with sharp corners, 3 mm deep, tool centre 3 mm outside it)
N500 G0 X3 Y-2
N510 G1 Z-3 F150
N520 G1 Y0 F500
N530 G1 X47
N540 G3 X50 Y3 I0 J3
N550 G1 Y37
N560 G3 X47 Y40 I-3 J0
N570 G1 X3
N580 G3 X0 Y37 I0 J-3
N590 G1 Y3
N600 G3 X3 Y0 I3 J0
N610 G0 Z5
N620 M5
N630 G0 X0 Y0 Z20
N640 M30
%
