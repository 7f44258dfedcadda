.word 5
tr 0, x1, y1,5233, -0.3
//.word 5
