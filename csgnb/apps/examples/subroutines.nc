(written for csgnb in the style of a hand-written LinuxCNC program: subroutines, loops, expressions)
#<_depth> = 2.0
#<_step> = 0.5
#<_safe> = 5
o<pocket> sub
  (#1 = centre x, #2 = centre y, #3 = radius)
  #<z> = 0
  G0 X[#1 + #3] Y#2
  G0 Z[#<_safe>]
  G1 Z0 F200
  o10 while [#<z> GT -#<_depth> + 0.0001]
    #<z> = [#<z> - #<_step>]
    G2 X[#1 + #3] Y#2 Z#<z> I-#3 J0 F400
  o10 endwhile
  G2 X[#1 + #3] Y#2 I-#3 J0
  G0 Z#<_safe>
o<pocket> endsub

G21 G17 G90 G64 P0.01
T1 M6
M3 S12000
G10 L2 P1 X0 Y0 Z0
G54
o20 repeat [3]
  o<pocket> call [10 + 15 * #30] [10] [4]
  #30 = [#30 + 1]
o20 endrepeat
G0 Z20
M5
M2
