domain data
0 0 0 0 0
nan 0 1 0 1
