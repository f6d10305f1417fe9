"""The paper's chain on every core with the bits of one: picks run by regions on the xoshiro stream
(`regions`) or by deterministic reservations on the counter stream (`reservations`); how threads wait, how
many there are, and when one thread is faster (`tuning`)."""
