.word 5
tr 0, x1, y1,5267,0.3



