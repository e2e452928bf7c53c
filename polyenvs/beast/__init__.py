"""The Platonic beasts: spherically symmetric robots with an RRR limb on each face, rolling by tumbles (MuJoCo).

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots"
(``../shared/seeds/002_*.txt``); spec ``../shared/spec/beast.md``.

| module | what |
| --- | --- |
| ``kinematics`` | Tables 1 and 2: limb frames, forward/inverse kinematics, the limb Jacobian, the 12 tumbles (numpy only) |
"""
