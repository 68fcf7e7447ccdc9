# band: one narrow opaque band at mid-range (a sharp transfer function)
name band
domain normalized
0.00  0 0 0 0
0.47  0 0 0 0
0.50  1 1 1 0.9
0.53  0 0 0 0
1.00  0 0 0 0
