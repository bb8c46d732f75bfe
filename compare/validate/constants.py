"""What ``tippetop validate`` needs before any run (its parser imports only this)."""

#: Simulated seconds of every run unless --t-end-s says otherwise.
DEFAULT_T_END_S = 8.0
