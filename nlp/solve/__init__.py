"""Solving the updating NLP (Eqn 25): the problem built once in CasADi, compiled pieces, scatter
search, Newton polish, identifiability, the search checkpoint, continuation starts, and the
executors that run independent starts (:mod:`.executors`)."""
