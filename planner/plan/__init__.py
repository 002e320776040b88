"""The planning stages of one unit of work: approach samples, the sweep of
candidates, closing the hand in the simulator, reading the contacts, scoring
them (``planner.quality``), reachability. The pools that run units are
:mod:`planner.run`'s."""
