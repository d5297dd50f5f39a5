"""The loops: a whole run of an ensemble through time, with its observers and stops, on the CPU.

The one time loop over a block of samples (:mod:`.block_loop`, its parts :mod:`.block_parts` and the free body's
:mod:`.free_body_parts`) and its drivers (:mod:`.drivers` for the free body, :mod:`.model_loop` for the built-in
systems and a user's System); the methods by name (:mod:`.methods`); a system given by its rate, one sample at a time
(:mod:`.sample_loop`, also run by the device), and to a tolerance, each sample its own steps (:mod:`.adaptive_loop`);
the tangent flow and the chaos indicators (:mod:`.tangent_blocks` on
blocks, :mod:`.tangent_loop` per sample).
"""

__all__ = ["adaptive_loop", "block_loop", "block_parts", "drivers", "free_body_parts", "methods", "model_loop", "sample_loop",
           "tangent_blocks", "tangent_loop"]
