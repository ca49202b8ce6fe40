"""Multi-session mapping with change detection: the building blocks of LT-Exosense (seeds/000 III-A/B).

- :mod:`.place_recognition`: ORB bag-of-binary-words vocabulary trained in the project, TF-IDF
  and DBoW2's L1 score, a keyframe database (III-B.1).
"""
