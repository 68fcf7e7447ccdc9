# warm: transparent low values, warm colours and rising opacity above
name warm
domain normalized
0.00  0.00 0.00 0.00 0.00
0.25  0.10 0.20 0.90 0.00
0.45  0.20 0.50 1.00 0.03
0.65  1.00 0.80 0.20 0.12
1.00  1.00 0.20 0.10 0.45
