name loglab
scale log
colorspace lab
domain normalized
0 0.9 0.2 0.1 0
0.5 0.5 0.5 0.5 0.1
1 0.1 0.3 0.8 0.8
