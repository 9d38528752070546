"""The paper's two tasks as users of the library: what is specific to the pendulum and to the
nunchaku (env, mentor, randomisation, the experimenter's pushes, the physical success check, the
end-to-end job) lives here, never inside petri/learn/adapt/runtime. Each is a
:class:`multiform.Task` subclass; load them by name with :func:`multiform.load_task`."""
