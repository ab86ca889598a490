# SPDX-License-Identifier: MIT
# maxdiff.py A B: the largest coordinate difference of two position dumps (tdiag OUT=)
import numpy as np,sys
a=np.fromfile(sys.argv[1]);b=np.fromfile(sys.argv[2])
print('maxdiff %.3g'%np.abs(a-b).max(), 'ndiff', int((a!=b).sum()), 'of', a.size)
