"""The mentor's side of teaching: recording a mentor's demonstrations (scripted, at a keyboard or a
joystick), and labelling segments of demonstrations and trials."""
