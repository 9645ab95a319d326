"""Calls a type checker must flag (tests/test_typing.py): the stub is what it reads."""

import quatarray as qa

q = qa.random(10)
qa.as_euler(q, 3)  # the sequence is a string
qa.slerp(q, q, 0.5, shortest="yes")  # a bool
qa.no_such_function(q)  # not a quatarray name
