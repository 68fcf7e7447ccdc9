nan 1 0.5 0.25 0.75  # missing
domain data
5 1 1 1 1
7 0 0 0 0
