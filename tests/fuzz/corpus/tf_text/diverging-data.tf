colorspace diverging
domain data
-1 0.23 0.30 0.75 0.5
0 0.3 0.3 0.3 0
2 0.71 0.02 0.15 1
