colorspace wrapped-hsv
domain data
0 1 0 0 1
1 0 0 1 1
colorspace step
