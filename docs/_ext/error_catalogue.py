"""Every error message a user of the command line can meet, by topic, with what it means and
what to do: ``conf.py`` writes the troubleshooting page's catalogue from :data:`TOPICS`, and
``tests/test_docs.py`` fails when a message in the package's source has no entry
(:func:`source_messages`, :func:`uncatalogued`).

A message is known by its *template*: its text as the source writes it, with ``…`` for every
value filled in at run time (``unknown scene …; built-in scenes: …``). An entry matches every
message whose template starts with the entry's (a stable prefix), so an entry may stop before
the part of a message that is likely to be reworded.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

# The calls whose first argument is a message the command line prints as `error: …`: the
# exceptions its commands turn into that line, and the commands' own `fail` helpers.
MESSAGE_CALLS = {"ValueError", "TypeError", "SceneError", "BackendError", "CheckpointWriteError", "fail", "_fail"}

# What a command prints before a message; the lines it echoes itself carry it in the source.
_PRINTED = "error: "

# (title, what the topic's errors have in common, [(message template prefix, what it means, what to do)])
TOPICS = [
    ("Command line", "How the command line itself reports what it cannot take.", [
        ("… (see '… --help')", "click refused the command line: an unknown option (`No such option`), a value of the wrong type or not among the choices (`Invalid value`), a missing argument", "run the command with `--help`: it lists the options, their types and choices"),
        ("--overwrite and --resume exclude each other", "`--overwrite` deletes the earlier render, `--resume` continues it", "give one of them"),
        ("… needs --ray", "`--address` and `--workers` configure Ray", "add `--ray`, or drop the option"),
        ("--address needs --ray", "`--address` names a Ray cluster", "add `--ray`, or drop `--address`"),
        ("--until-noise compares the render's error with a sensor's noise: give --sensor", "`--until-noise` stops when the Monte Carlo error falls below a sensor's noise, which needs a sensor", "add `--sensor PRESET`, or drop `--until-noise`"),
        ("--camera and --sensor exclude each other", "a sensor's raw frames define the cameras", "give `--camera` options or `--sensor`, not both"),
        ("aborted", "the command was interrupted at a prompt or before it started work", "run it again"),
        ("interrupted while starting; nothing done", "Ctrl-C while the command still imports the package (its first third of a second)", "run the command again"),
        ("interrupted before the first pass finished; nothing written", "Ctrl-C (or SIGTERM, SIGHUP) before any pass was done", "run the command again; a later interruption keeps the finished passes"),
        ("interrupted after the record was written…: the same command with … -o ANOTHER_FOLDER… sweeps it without rendering", "`dopplertof design` was stopped in its sweep, after writing the record(s)", "the `--record` options it names, with another output folder"),
        ("interrupted after the records were read", "`dopplertof design --record …` was stopped in its sweep", "run it again"),
        ("interrupted before the record was finished", "`dopplertof design` was stopped (Ctrl-C, SIGTERM, SIGHUP) while it rendered a record; the message lists the records of earlier scenes it kept, else says nothing was written", "run it again (`--record` reuses the kept records)"),
        ("…; free space, then …", "a checkpoint could not be written mid-render (a full disk); the message says whether an earlier one is kept", "free space, then what the message says: the same command with `--resume` where a checkpoint is kept, else the command again"),
        ("stopped at once; the checkpoint … keeps … finished pass… (continue with --resume)", "a second Ctrl-C (or SIGTERM, SIGHUP) stopped at once; a checkpoint being written is finished first", "the same command with `--resume` continues (and writes the images)"),
        ("stopped before a pass was saved; nothing written", "a second signal came before the first checkpoint", "run the command again"),
        ("output folder … is being written by another dopplertof process; wait for it to finish, or choose another folder", "two commands at once into one output folder (each would replace some of the other's files)", "wait, or use another folder"),
        ("… holds the … experiment's tables; this one (…) would replace them and leave its plots: choose another folder", "an experiment into another experiment's folder", "another folder per experiment (the same experiment replaces its own tables)"),
        ("output folder … holds …; … would mix with it: use another folder", "the folder holds another command's output (a render, an experiment's tables, a dataset, an animation, a design study)", "give another `-o` folder"),
        ("cannot write …: …", "an output file could not be written (a full disk, no permission); the message names the file and the reason", "free space or fix the permission; where the message says the sums are kept, rerun with `--resume`"),
        ("unknown experiment …; choose one of …", "`dopplertof experiment` has no experiment of that name", "use one of the names listed"),
        ("unknown --waveform …; choose one of …", "`--waveform` names a waveform the experiments do not know", "use one of the names listed"),
        ("reference cache: …", "the reference cache folder cannot be used (the message says why)", "give another `--cache` folder"),
        ("say what to do: --print, --markdown or --check FILE", "`dopplertof dataset config` needs an action", "add `--print`, `--markdown` or `--check FILE`"),
        ("give --sweep KEY=LO:HI:N and/or --optimize KEY", "`dopplertof design` has nothing to explore", "give a sweep or a key to optimise"),
        ("--sweep: each key once", "a design key was swept twice", "give each key in one `--sweep`"),
        ("--rmse-draws: 0 (none) or at least 2 noise draws, got 1", "an RMSE over one noise draw has no spread", "0, or 2 draws and more"),
        ("--sweep …: … must be > 0 (…), LO is …", "a swept frequency or exposure at or below zero", "a positive LO"),
        ("--sweep …: its points are … Hz apart, and a record's frequencies are whole Hz: choose LO, HI and N so that (HI - LO)/(N - 1) is whole Hz", "the record's frequency grid is in whole Hz", "e.g. `f=10e6:100e6:10`"),
        ("the sensor has no heterodyne frame (every h = 0): a heterodyne sweep changes nothing", "`--sweep h=…` on a homodyne sensor (an AMCW chip)", "sweep `f` or `T`, or a sensor with heterodyne frames"),
        ("every point of the sweep is refused, e.g. …", "no point of the sweep can be captured by the sensor (found before the record is rendered)", "the reason given; `sweep.csv` of a partly refused sweep lists each"),
        ("--optimize modulation_frequency: the sensor has no frequency range to search (no preset's chip limits, one frequency): give --sweep f=LO:HI:N to span one, or a sensor file with a preset", "a sensor file without a preset has no chip range to search, and the optimiser would report its start as the optimum", "a `--sweep f=…` beside it, or `preset = …` in the file"),
        ("… holds an earlier design run (…); choose another folder, --overwrite, or --resume to continue it", "the output folder has another design run's files (or an interrupted run's checkpoint)", "use another folder, `--overwrite`, or `--resume` to continue an interrupted run"),
        ("--resume continues the records rendered in …: … excludes it", "`--resume` with `--overwrite` (which removes the run it would continue) or `--record` (which renders nothing)", "leave one of them out"),
        ("--resume: … was rendered by another command (other sweeps or render settings); remove it, or give that command", "the record that `--resume` would read was rendered with another grid or other render settings than the command asks for", "give the interrupted command again with `--resume`, or another folder"),
        ("…: no moving pixel (the ground-truth velocity is zero everywhere in the exposure); the design's objective is the mean bound over the moving pixels", "nothing moves in the scene's view during the exposure (a static scene, or motion that ends before it), so there is nothing to average the bound over", "design on a scene where something moves, or an exposure within its motion"),
        ("every point of the sweep was refused or has an infinite bound (see sweep.csv)", "no design point of the sweep gives a finite error bound", "widen the sweep; `sweep.csv` says why each point failed"),
    ]),
    ("Scenes", "Choosing a scene by name or file, and the options that change it.", [
        ("…: no such scene file or built-in scene (see 'dopplertof scenes')", "SCENE is neither a file nor a built-in scene name", "check the path (relative to the working folder); `dopplertof scenes` lists the names"),
        ("unknown scene …; built-in scenes: …", "no built-in scene has that name", "use one of the names listed"),
        ("unknown scene recipe …", "a Ray worker was asked to rebuild a scene it cannot describe (a scene from a dict)", "load the scene from a file or a built-in name to render it with `--ray`"),
        ("scene … has no parameter(s) …; it takes …", "a built-in scene was given a keyword it does not have", "use the keywords listed"),
        ("--resolution …: expected N or WxH (positive integers)", "`--resolution` is not a film size", "give `64` or `128x96`"),
        ("--resolution …: built-in scenes are square; give one number", "the built-in scenes take one size", "give `N`"),
        ("-D …: expected name=value (name: letters, digits, _)", "a `-D` option is not `NAME=VALUE`", "write `-D speed=2.5`"),
        ("-D applies to scene files; … is a built-in scene", "`-D` sets a scene file's `$NAME` values", "drop `-D`, or render a file"),
        ("resolution must be a positive integer, got …", "a built-in scene's film size is not a positive integer", "give a positive integer"),
        ("… must be a finite number > 0, got …", "a built-in scene's size, speed or time is zero, negative or not a number", "give a positive number in the unit the message names"),
        ("light must be 'point' or 'area', got …", "the scene's light kind is unknown", "`point` or `area`"),
        ("keyframes must be a positive integer (intervals of the fall), got …", "the falling box needs at least one keyframe interval", "give a positive integer"),
        ("spin_deg must be a finite number of degrees, got …", "the falling box's spin is not a number", "give degrees"),
        ("spin_deg=… is too much for … keyframe intervals (< 180° each)", "keyframed rotations take the short way, so one interval must turn less than 180°", "more `keyframes`, or less spin"),
        ("count must be a positive integer, got …", "the domino chain needs at least one domino", "give a positive integer"),
        ("spacing=… m must exceed the thickness … m (dominoes would overlap)", "the dominoes would intersect", "a larger spacing or thinner dominoes"),
        ("spacing=… m leaves a gap of at least the height … m", "a falling domino would not reach the next", "a spacing below the height"),
        ("push=… rad/s does not tip a domino over its edge; use a larger push", "the first domino would rock back", "a larger `push`"),
    ]),
    ("Render settings", "A setting of `dopplertof render` (or of the API's `RenderSettings`), from an option, a scene file's `<integrator>` or a dict. The message names the setting and the values it takes; the settings table of the [command line](cli.md) page lists them all.", [
        ("unknown … …; choose one of …", "a choice setting (time sampling, correlation, …) has a value it does not know", "use one of the choices listed"),
        ("…: unknown camera key… …; the keys are …", "`Camera.from_original` given a key the original code does not have (a misspelling)", "use one of the keys listed"),
        ("… must be >= …, got …", "a setting is below its minimum", "give a value at or above the minimum (the settings table of the [command line](cli.md) page)"),
        ("… must be …, got …", "a setting is out of its range or of the wrong type (a number where an integer is needed, …)", "give a value in the range the message names"),
        ("… must be true or false, got …", "a boolean setting got another value", "`true` or `false` (also yes/no, 1/0, on/off in files)"),
        ("'checkpoint_interval_s' must be >= 0 seconds, got …", "a negative checkpoint interval", "0 (every pass) or more seconds"),
        ("checkpoint=… must name a file", "`dt.render(checkpoint=...)` got an empty path or a folder", "a file name, e.g. `out/checkpoint.npz`"),
        ("checkpoint=…: its folder … does not exist (or is a file)", "the checkpoint's folder is missing, or is a file", "create the folder first"),
        ("checkpoint=…: its folder … cannot be written", "no permission to write the checkpoint's folder", "another folder"),
        ("'max_depth' must be >= 1 or -1 (unbounded), got …", "a path depth of 0 or below -1", "1 or more, or -1"),
        ("'seed' must be < 2**32, got …", "seeds are 32-bit", "a seed in [0, 2³²)"),
        ("… pairs exactly 2 times, got n_times=…", "antithetic mirror sampling pairs two times per group", "`n_times = 2`"),
        ("antithetic needs n_times >= 2, got …", "antithetic sampling shifts at least two times per group", "`n_times` of 2 or more"),
        ("'antithetic_shift' must be in [0, 1] (units of T), got …", "the antithetic shift is a fraction of the exposure", "a value in [0, 1]"),
        ("'antithetic_shift' applies to antithetic sampling, not …", "the shift has no meaning for the chosen time sampling", "drop it, or choose `antithetic`"),
        ("'correlation_depth' applies to replay; … does not use it", "a setting the correlation mode ignores", "drop it, or use `--correlation replay`"),
        ("'reconnection_threshold' applies to adaptive correlation, not …", "a setting the correlation mode ignores", "drop it, or use `--correlation adaptive`"),
        ("correlation=… pairs two times (n_times=2), got n_times=…", "reconnection and adaptive correlation pair a path with one partner", "`n_times = 2`"),
        ("spp=… must be a multiple of the … correlated times per group", "a pixel's paths come in groups of `n_times`", "an spp that is a multiple of `n_times`"),
        ("'cameras' must be a list of dopplertof.Camera, got …", "the API's `cameras` is not a list of cameras", "pass `[dt.Camera(...), ...]`"),
        ("analytic time integration needs a fully correlated partner", "analytic integration over time needs a replayed or reconnected partner", "`--correlation replay`, `reconnection` or `adaptive`, or drop analytic integration"),
        ("analytic time integration is implemented for the low-pass sinusoid only", "analytic integration supports only the low-pass sinusoid", "use `waveform=sinusoid` with `low_pass`, or drop analytic integration"),
        ("exposure=… s differs from the cameras' exposure … s", "the exposure setting and the cameras' T disagree", "give one exposure (`--exposure` sets every camera's T)"),
        ("…: <integrator type=…> is …; use type 'dopplertof'", "a scene file's integrator is not one dopplertof renders", "`<integrator type=\"dopplertof\">` or a stock `path` integrator"),
        ("…: <integrator type=…> does not take …", "D-ToF parameters on a stock path integrator", "move them into `<integrator type=\"dopplertof\">`"),
        ("…: give either 'correlation'/'correlation_depth' or 'path_correlation_depth', not both", "the original name and the SI names of one setting were both given", "keep one"),
        ("…: 'path_correlation_depth' must be >= 0, got …", "the original code's correlation depth is negative", "0 or more"),
        ("…: 'm_reconnection_threshold' must be >= 0, got …", "the original code's reconnection threshold is negative", "0 or more"),
        ("…: give either … or …, not both", "a setting was given by its original name and by its SI name", "keep one"),
        ("…: the sensor's shutter is open for … s but the <integrator> exposure … is … s", "the film's shutter interval and the integrator's exposure disagree", "make them agree or remove one"),
        ("…: the sensor's shutter opens at … s but the <integrator> exposure_start is … s", "the shutter's opening and the integrator's `exposure_start` disagree", "make them agree or remove one"),
        ("…unknown setting …", "a setting name that does not exist (in a dict, a file's `<integrator>` or `RenderSettings`)", "the message suggests the closest name; the settings table lists them all"),
    ]),
    ("Cameras", "A `--camera` value, a scene file's camera parameters or a `dt.Camera`.", [
        ("camera …: empty; give key=value pairs such as 'h=1,psi=90deg'", "an empty `--camera`", "give `key=value` pairs"),
        ("camera …: expected key=value, got …", "a `--camera` item is not `key=value`", "write `h=1,psi=90deg`"),
        ("camera …: unknown key …; use …", "a `--camera` key does not exist", "use the keys listed"),
        ("camera …: … given twice", "a `--camera` key appears twice", "give it once"),
        ("camera …: …=… is not a number", "a `--camera` value does not parse", "numbers; angles in rad or with `deg`: `psi=90deg`"),
        ("camera …: …", "a `--camera` value is out of range (the message says which)", "see the Camera parameters of the [API reference](reference.md)"),
        ("… must be in (0, …] s, got …", "an exposure T or start time outside its range", "seconds: 1.5 ms is `1.5e-3`"),
        ("unknown waveform …; choose one of …", "a waveform name that does not exist", "use one of the names listed"),
        ("Camera: modulation_frequency must be in (0, …] Hz, got …", "f_g outside its range", "Hz: 30 MHz is `30e6`"),
        ("Camera: |heterodyne| must be <= … beat cycles per exposure, got …", "h too large", "h counts beat cycles per exposure"),
        ("Camera: 'g1' (light modulation amplitude) must be …, got …", "the light's modulation amplitude is out of range", "a value in the range named"),
        ("Camera: 'g0' (light DC offset) must be >= 0, got …", "a negative DC offset", "0 or more"),
        ("Camera: unknown waveform …; choose one of …", "a waveform name that does not exist", "use one of the names listed"),
        ("Camera: give both light_code and sensor_code, or neither", "a code camera needs both codes", "give both"),
        ("Camera: waveform=… and light_code/sensor_code exclude each other", "a camera has a waveform or codes", "drop one"),
        ("Camera: light_bandwidth applies to cameras with light_code and sensor_code", "the light's bandwidth limits a code", "drop it, or give codes"),
        ("Camera: light_bandwidth=… Hz is below the modulation frequency", "no harmonic of the modulation would reach the scene", "a bandwidth of at least f_g"),
        ("Camera: light_bandwidth=… Hz passes more than … harmonics", "a bandwidth so high that it is no limit", "leave it None (unlimited)"),
        ("named: the … waveform has no exact chip code; choose one of", "`light_bandwidth` turns a named waveform into its chip code, which only some waveforms have", "one of the waveforms listed, or your own code"),
    ]),
    ("Output folders and checkpoints", "Where results are written, and continuing an interrupted render.", [
        ("output … exists and is not a folder", "`-o` names a file", "give a folder"),
        ("output … lies under …, which is a file", "a parent of `-o` is a file", "give another path"),
        ("output folder … has … MB free; this render writes about … MB", "not enough disk space for the render's files and checkpoint", "free space or use another folder"),
        ("output folder … holds …; use --overwrite (overwrite=True) to replace them, or another folder", "another render's files are there", "`--overwrite` replaces them (only them), or use another folder; `--resume` continues an interrupted render"),
        ("output folder … is not writable (…)", "the folder is read-only or not yours", "use another folder"),
        ("-o/--output is empty; leave it out for the default folder (…)", "`-o \"\"` (an unset shell variable, say)", "a folder name, or no `-o` for the default"),
        ("…=… exceeds its maximum …: …", "a setting above its maximum (`spp` above 2³¹: the most paths per pixel one render takes)", "what the message says (for `spp`: render several times with different seeds and average)"),
        ("…: the checkpoint belongs to a render with other settings or another scene", "`--resume` found a checkpoint of a different render", "resume with the same settings, remove the checkpoint or use another folder"),
        ("…: the checkpoint cannot be read (…); remove that file to render from the start", "the checkpoint file is unreadable", "remove `checkpoint.npz`"),
        ("…: the checkpoint is damaged (… missing or of another shape)", "the checkpoint file is incomplete", "remove `checkpoint.npz`"),
    ]),
    ("Rendering", "Limits of one render (and the API's `dt.render`).", [
        ("the film must be at least 1x1 pixels, got …x…", "an empty film", "give a positive resolution"),
        ("a …x… film with … camera(s) needs about … GiB of memory for its buffers; … GiB are available", "the film's per-pixel sums do not fit in memory", "a smaller film or fewer cameras"),
        ("render() takes a scene from dopplertof.load_scene(...) or dopplertof.scenes.build(...), got …", "the API's `render` got something else: a dict, a path, or a scene Mitsuba loaded (`mi.load_dict`, `mi.load_file`)", "load the file or dict with `dt.load_scene`; a static `mi.Scene` also renders with `mi.render` and the `dopplertof` integrator"),
        ("executor must be one of …, got …", "an unknown executor", "`local` or `ray`"),
        ("address and workers apply to executor='ray'", "Ray options without Ray", "`executor=\"ray\"`, or drop them"),
        ("stop must be a callable returning True to stop, got …", "the API's `stop` is not callable", "pass a function"),
        ("sensor must be a dopplertof.Sensor, got …", "the API's `sensor` is of another type", "pass `dt.sensors.preset(...)` or a `dt.Sensor`"),
        ("give cameras or sensor, not both", "a sensor's raw frames are its cameras", "drop `cameras`"),
        ("settings must be a dopplertof.RenderSettings or a dict of setting names, got …", "the API's `settings` is of another type", "pass a `RenderSettings` or a dict"),
        ("until_noise=…: needs a sensor (sensor=...)", "`until_noise` compares the render's error with a sensor's noise, and no sensor was given", "give `sensor=`"),
        ("until_noise=…: must be > 0", "`until_noise` (`--until-noise`) is a ratio of the Monte Carlo error to the sensor's noise: zero or negative can never be reached", "a ratio > 0, e.g. 0.5"),
        ("record: a response record is rendered locally (executor='local')", "`record=` with Ray", "render the record locally"),
        ("record: a response record of the … correlation is rendered as several renders of probe cameras, without a checkpoint (checkpoint=None)", "`record=` and `checkpoint=` with the `adaptive` or `reconnection` correlation, whose record is several renders", "leave out `checkpoint`, or record with `correlation='replay'`"),
        ("the dopplertof integrator renders the scene's first sensor only, got …", "`mi.render(scene, sensor=…)` with another sensor", "put the sensor first in the scene"),
        ("mi.render cannot render a dopplertof scene (its bodies move at per-path times)", "stock Mitsuba cannot move bodies", "`dopplertof.render(scene)`"),
        ("the dopplertof integrator only supports develop=True", "the plugin returns developed images", "`mi.render(..., develop=True)`"),
        ("the film's reconstruction filter … has negative lobes", "Mitsuba's Lanczos or Mitchell filters are not supported", "box, tent or gaussian"),
        ("BSDF … (…) transmits light through the surface, and the optical path length through it is not known here", "a BSDF that transmits light other than a dielectric of its own: principled with spec_trans > 0, a dielectric inside mask or blendbsdf", "use dielectric or roughdielectric on its own (thindielectric, null, mask around an opaque BSDF are fine)"),
        ("mover must be 'plane' or 'camera', got …", "the moving-plane oracle moves the plane or the camera", "one of the two"),
        ("workers must be a positive integer, got …", "`--workers` below 1", "1 or more"),
        ("--ray needs the 'ray' package: pip install 'dopplertof[ray]'", "Ray is not installed", "`pip install 'dopplertof[ray]'`"),
        ("the Ray executor builds the scene again on every worker, from its file or built-in name", "a scene loaded from a dict cannot be sent to Ray workers", "save it as a Mitsuba XML file, or render it locally"),
        ("cannot reach the Ray cluster at … within … s (…)", "the Ray address does not answer", "check `--address`; without it a local Ray starts"),
        ("cannot connect to Ray at …: …", "Ray refused the connection", "check `--address` and that the cluster runs"),
    ]),
    ("Velocity reconstruction and animations", "`dopplertof reconstruct` and `dopplertof animate`.", [
        ("no cameras: velocity reconstruction needs D-ToF measurements", "the render has no measurement to reconstruct from", "render with homodyne and heterodyne cameras, e.g. h=0 and h=1 at ψ = 0 and 90°"),
        ("…: … measurement file for camera … (measurement_…_h*.exr)", "a measurement image of the render folder is missing or duplicated", "render the folder again"),
        ("…: no such folder", "the folder does not exist", "give the `-o` folder of `dopplertof render`"),
        ("…: not a 'dopplertof render' output folder (no …)", "the folder holds no render", "give the `-o` folder of `dopplertof render`"),
        ("…: … missing (the render wrote …: the standard errors judge which pixels are valid); restore … or render again", "a render folder that lost some of its `*_stderr.exr` files or `measurement_covariance.npy`", "restore them, or render again"),
        ("…: the render has no D-ToF camera", "the render has no measurement", "render with `--camera` options (the message lists four)"),
        ("…: measurement images must be single-channel and of one size, got shapes …", "the measurement images were changed", "render the folder again"),
        ("…: shape … differs from the measurements' …", "a map of the folder has another size than the measurements", "render the folder again"),
        ("--max-velocity-stderr must be a speed > 0 in m/s (e.g. 0.5 or 0.5m/s), got …", "the validity threshold is not a positive speed", "give m/s"),
        ("…: cannot read its cameras (…)", "the folder's `metadata.json` is unreadable", "render the folder again"),
        ("all cameras have the same heterodyne ratio h = …", "homodyne cameras only (or one h): the Doppler shift only scales them", "add h = 1 next to h = 0"),
        ("the cameras … cannot determine velocity", "these cameras cannot tell a moving surface's brightness change from a Doppler shift", "add the cameras the message names (h = 0 and 1 at ψ = 0 and 90°)"),
        ("frames must be a positive integer, got …", "`--frames` is not a positive integer", "give a positive integer"),
        ("fps must be a finite number of frames per second > 0, got …", "`--fps` is not positive", "give frames per second"),
        ("fps must be >= … frames per second", "a GIF cannot hold a frame that long", "a higher `--fps`"),
        ("an animation opens every camera's exposure at its frame's time", "cameras with their own `exposure_start` (a capture schedule)", "drop `start=` from the cameras"),
        ("… holds an animation with other settings (…); use another folder, or --overwrite to replace it", "the folder holds another clip", "use another folder, or `--overwrite`"),
        ("… has frame folders but no …; use another folder, or --overwrite to replace them", "the folder holds frames of an unknown clip", "use another folder, or `--overwrite`"),
        ("…: its motion has no end (or nothing moves); give --frames", "the clip's length cannot be taken from the scene", "give `--frames`"),
        ("…() needs the cameras (or a RenderResult)", "the API's `velocity` or `depth` was given bare measurements", "pass `cameras=` or the `RenderResult`"),
        ("method must be 'auto', 'ratio' or 'fit', got …", "an unknown reconstruction method", "one of the three"),
        ("max_doppler_hz must be a finite number > 0, got …", "the fit's Doppler bound is not positive", "a frequency in Hz"),
        ("max_velocity_stderr=… m/s needs the measurements' errors", "the validity threshold needs standard errors", "pass the `RenderResult`, or `measurement_stderr`"),
        ("max_velocity_stderr must be > 0 m/s, got …", "the validity threshold is not positive", "a speed in m/s"),
        ("stderr_dof must be >= 0 (degrees of freedom), got …", "a negative number of degrees of freedom given to `reconstruct.velocity`", "the render's `info[\"stderr_dof\"]`, or leave it out"),
        ("cameras at … modulation frequencies (… MHz): velocity() combines two", "more than two modulation frequencies", "reconstruct the others separately"),
        ("the cameras at … MHz differ in exposure", "the cameras of one frequency have different T", "one exposure for all cameras"),
        ("the cameras at … MHz open their first windows at different times", "two frequencies' depths refer to different instants", "the same first window for both frequencies"),
        ("the cameras at modulation_frequency = … MHz (beside … MHz, reconstructed on their own): …", "the cameras of one of two frequencies cannot give velocity; the message says why", "see the rest of the message"),
        ("depth needs at least two independent phase measurements", "one phase cannot give a distance", "homodyne cameras at ψ = 0 and π/2"),
        ("cameras is empty; need at least one camera configuration", "no cameras", "pass the render's cameras"),
        ("modulation_frequency must be > 0 Hz, got …", "a camera without modulation", "f_g in Hz"),
        ("exposure must be > 0 s, got …", "a camera without exposure", "T in seconds"),
        ("g1 must be > 0, got …", "a camera without light modulation", "g₁ > 0"),
        ("all cameras must share one modulation_frequency (f_g)", "the model needs one f_g", "reconstruct each frequency separately"),
        ("all cameras must share one exposure (T), got … s", "the model needs one T", "render the cameras with one exposure"),
        ("some cameras give an exposure_start and others do not", "the cameras' windows are unknown", "pass the `RenderResult` or its `result.cameras`"),
        ("camera exposure_start must be finite, got … s", "a camera's start time is not a number", "seconds, or None"),
        ("…; got waveform(s) …; use waveform='sinusoidal'", "the reconstruction model is the low-pass sinusoid's", "render with `waveform=sinusoidal`"),
        ("measurements must have shape (n_cameras, ...) with n_cameras = …, got shape …", "as many images as cameras are needed", "pass `result.measurements`"),
        ("min_amplitude must be a finite number >= 0, got …", "a negative amplitude threshold", "0 or more"),
        ("modulation_frequency_hz must be > 0, got …", "no modulation frequency", "Hz"),
        ("each camera needs modulation_frequency, exposure, heterodyne and phase attributes", "the API's cameras are of another type", "pass `dt.Camera` objects"),
        ("camera … must be finite, got …", "a camera parameter is NaN or infinite", "finite values"),
        ("measurement_stderr must have the measurements' shape …, got …", "standard errors of another shape", "pass `result.measurement_stderr`"),
        ("measurement_stderr must be >= 0 (standard errors), got … negative values, e.g. …", "negative standard errors", "pass `result.measurement_stderr`"),
        ("measurement_covariance must have shape …, got …", "a covariance of another shape", "pass `result.measurement_covariance`"),
        ("method='ratio' needs every camera in a homodyne (h=0) / heterodyne (h=1) pair", "the ratio method pairs cameras", "pairs of h = 0 and h = 1 at equal phases, or `method='fit'`"),
        ("method='ratio' with pairs at … would read the brightness change of a moving surface as velocity", "the pairs' phases do not balance", "ψ = 0 and 90°, or `method='fit'`"),
    ]),
    ("Experiments", "`dopplertof experiment`.", [
        ("… must be a positive multiple of … (paths of an antithetic pair), got …", "the experiments render antithetic pairs", "an even spp"),
        ("… must be an integer >= 2, got …", "a sweep needs at least two values", "2 or more"),
        ("--… must be an integer >= …, got …", "an `experiment` count (`--spp`, `--reference-spp`, `--resolution`, `--h-steps`, `--phases`, `--shift-steps`, `--phase-steps`) below its least value", "the least value named or more"),
        ("--max-depth must be >= 1 or -1 (unbounded), got …", "an `experiment` path depth of 0 or below -1", "1 or more, or -1"),
        ("phases must be an integer >= 1, got …", "a sweep needs at least one phase", "1 or more"),
        ("need at least one h and one phase, got h=…, psi=…", "an empty sweep grid", "give h values and phases"),
        ("the shift experiment needs an antithetic time sampling", "only antithetic sampling has a shift", "`antithetic` or `antithetic_mirror`"),
        ("signal electrons must be a finite number > 0, got …", "the sensor's signal level is not positive", "give electrons, e.g. `1e4`"),
        ("the reference image is black: no light reaches the camera", "nothing to measure", "check the scene's light and camera"),
    ]),
    ("Datasets", "`dopplertof dataset` and `dt.dataset.generate`.", [
        ("config must be a TOML file path, a dict or None, got …", "the API's `config` is of another type", "pass a path or a dict"),
        ("… must be an integer ≥ …, got …", "a count (samples, shard size) is too small", "give an integer at or above the minimum"),
        ("workers must be an integer ≥ 1 or …, got …", "`--workers` (`generate(workers=…)`) below 1", "a positive integer, or `auto` (one per CPU)"),
        ("workers=… counts local processes; with Ray each shard is a task of its own", "`--workers N` with `--ray`: Ray gives each shard a task and decides where it runs", "drop `--workers` (Ray uses its cluster's CPUs), or drop `--ray`"),
        ("shard range must be 'a:b' (shard indices, b excluded), got …", "`--shards` is not `a:b`", "write `0:4`"),
        ("shard range … is outside the dataset's … shards", "`--shards` names shards the dataset does not have", "a range within the one named"),
        ("datasets are rendered with an RGB variant (…), not …", "a mono variant is active", "`--variant llvm_ad_rgb` (or `cuda_ad_rgb`)"),
        ("seed must be < 2**63, got …", "the dataset seed is too large", "a seed below 2⁶³"),
        ("… holds another dataset (it differs in …); use another folder", "the folder holds a dataset of other settings", "use another folder, or the same settings to continue it"),
        ("unknown config key …", "a configuration key that does not exist", "`dopplertof dataset config --print` prints every key"),
        ("unknown config section […]; sections: …", "a configuration section that does not exist", "use the sections listed"),
        ("cannot read config file …: …", "the configuration file cannot be read", "check the path"),
        ("config file … is not valid TOML: …", "the configuration does not parse", "fix the TOML syntax at the place named"),
        ("config key … is not a distribution", "a fixed value where a range or weights are drawn", "write a range or weights"),
        ("config keys 'camera.heterodyne' and 'camera.phase_deg' must have the same length", "the capture set lists cameras pairwise", "as many phases as heterodyne ratios"),
        ("camera.modulation_frequency_hz and camera.exposure_s must be > 0", "no modulation or no exposure", "positive Hz and s"),
        ("config key 'camera.fov_deg' must lie in (0, 180) degrees, got …", "a field of view out of range", "degrees in (0, 180)"),
        ("config key 'sensor.adc_bits' must be ≤ … (raw taps are uint16), got …", "more ADC bits than the raw taps hold", "16 or fewer"),
        ("config key 'camera.g0' must be > 0", "the sensor model scales the signal by g₀", "g₀ > 0"),
        ("config key 'sensor.black_level_dn' must be below the ADC's maximum … DN, got …", "a black level the ADC cannot hold", "a smaller black level"),
        ("config key 'sensor.full_well_e' must be > 0, got …", "a sensor without full well", "electrons > 0"),
        ("config key 'materials.albedo' must lie in [0, 1], got …", "an albedo out of range", "values in [0, 1]"),
        ("config key … is a probability in [0, 1], got …", "a probability out of range", "a value in [0, 1]"),
        ("config key … must be > 0, got …", "a value that must be positive", "a positive value"),
        ("config key … must not be negative, got …", "a negative value", "0 or more"),
        ("config key 'render.spp' must be a multiple of 2 with paired times", "paired time sampling renders pairs", "an even spp"),
        ("config key 'render.spp' must be at least … (…, …: two independent groups", "one group of correlated times per pixel leaves no replicates: no standard errors, no camera covariance", "at least twice the group (4 with paired times, 2 with uniform)"),
        ("… lists no sensor, got …; leave it out (or '') for a dataset without a sensor", "`sensor.model` is an empty list", "name at least one sensor, or leave the key out"),
        ("… must be a sensor (preset name or .toml file), a list of them or a table {name = weight}", "`sensor.model` is of another form", "a preset name, a sensor TOML path, a list of them, or `{name = weight}`"),
        ("…: sensor … has a …-bit ADC", "a drawn sensor's digital numbers do not fit the field's 16 bits", "a sensor with an ADC of 16 bits or fewer"),
        ("field … needs a sensor: set the config key 'sensor.model'", "`raw_electrons`/`raw_dn` come from a sensor's raw frames", "set `sensor.model`, or drop the field from `fields`"),
        ("… must be an integer, got …", "a configuration value that must be an integer", "an integer"),
        ("… must be ≥ …, got …", "a configuration value below its minimum", "at least the minimum"),
        ("… must be a finite number, got …", "a configuration value that is not a number", "a number"),
        ("… must be one of …; got …", "a configuration choice that does not exist", "one of the choices listed"),
        ("… must be a range [min, max], got …", "a range is written as two numbers", "`[min, max]`"),
        ("… must be a range of integers [min, max], got …", "an integer range", "`[min, max]` of integers"),
        ("… must be a range of finite numbers [min, max], got …", "a range of numbers", "`[min, max]` of numbers"),
        ("… must not be negative, got …", "a negative value", "0 or more"),
        ("…: range min … > max …", "a range's ends are swapped", "`[min, max]` with min ≤ max"),
        ("…: a log-uniform range must be > 0, got …", "a log-uniform range must be positive", "positive ends"),
        ("… must be a non-empty list of finite numbers, got …", "a list of values is empty or holds non-numbers", "a list of numbers"),
        ("… must be a table {name = weight}, got …", "weights are a table", "`{name = weight}`"),
        ("…: unknown name(s) …; choose from …", "a weight names a choice that does not exist", "the names listed"),
        ("…: weights must be finite numbers ≥ 0, got …", "a negative or non-numeric weight", "weights ≥ 0"),
        ("…: at least one weight must be > 0, got …", "every weight is 0", "one positive weight"),
        ("no TOML form for …", "a value with no TOML form", "numbers, strings, lists and tables"),
        ("unknown material …", "a sample description names a material that does not exist (a damaged record)", "generate the dataset again"),
        ("unknown body shape …", "a sample description names a shape that does not exist (a damaged record)", "generate the dataset again"),
        ("unknown material type …", "a sample description names a material type that does not exist (a damaged record)", "generate the dataset again"),
        ("unknown primitive type …", "a sample description names a primitive that does not exist (a damaged record)", "generate the dataset again"),
        ("scene has … bodies, its description …: two bodies share a motion", "two bodies of a sample move identically and were merged", "a new seed"),
        ("unexpected member …", "a shard holds a file that is not a sample's", "`dopplertof dataset verify`; generate the bad shards again"),
        ("…: no …; not a dopplertof dataset folder", "the folder holds no `dataset.json`", "give the dataset's folder"),
        ("field … is not rendered for this capture set", "a camera covariance needs 2 to 8 cameras", "remove the field from the config's fields"),
        ("… is not valid JSON (…); remove it: the same 'dataset generate' command rebuilds it from the shards' records", "the manifest is damaged", "remove `dataset.json` and run the same `dataset generate` command: it rebuilds the manifest"),
        ("…: its contents differ from its record (SHA-256): damaged since it was written; 'dopplertof dataset verify' lists such shards, and the same 'dataset generate' command writes them again", "a shard's bytes changed after it was written (same size, other contents)", "`dataset verify`, then the same `dataset generate` command"),
        ("…: … changed since the render wrote … (SHA-256 in …); render again, or restore …", "a render folder's file was edited or damaged after the render wrote it (its bytes are not those `metadata.json` records)", "render again, or restore the file"),
    ]),
    ("Sensors", "`--sensor PRESET|FILE.toml` (see [sensors](sensors.md)).", [
        ("--sensor …: neither a preset (…) nor a .toml file", "`--sensor` names no preset and no file", "a preset listed or a TOML file"),
        ("…: not valid TOML", "the sensor file does not parse (or is not UTF-8 text)", "fix the TOML syntax at the place named"),
        ("[silicon] must be a table of Silicon parameters, got …", "`[silicon]` is not a table", "write `[silicon]` with `key = value` lines"),
        ("frames must be [[frames]] tables", "`frames` is not an array of tables", "write one `[[frames]]` table per frame"),
        ("a sensor without a preset needs [[frames]]", "the file defines no frames", "give `preset = …` or `[[frames]]`"),
        ("'taps' must be one of …, got …", "a tap count the sensor model does not have", "one of the counts listed"),
        ("'taps' is the preset's (…); remove it", "a preset fixes its taps", "remove `taps`"),
        ("unknown sensor preset …; choose one of …", "no preset of that name", "one of the names listed"),
        ("…: row … not in the … rows of …", "a code row index outside the code table", "a row that exists"),
        ("…: code table … not found (…)", "a `{ table = …, row = … }` code names a file that does not exist (relative to the sensor file)", "give the table's path relative to the sensor file"),
        ("sensor_toml: cannot write … as TOML", "a sensor setting has no TOML form", "use numbers, strings and lists"),
        ("unknown key… …", "keys the sensor file does not take (every one is named)", "the message suggests the closest key"),
        ("light_bandwidth: frame …: …", "a sensor file's top-level `light_bandwidth` does not suit a frame (the message says why)", "a bandwidth in Hz the frame accepts, or the frame's own `light_bandwidth`"),
        ("…: a code written as a dict has one key, 'samples' or 'fourier', got …", "a code in a sensor file has other keys", "`{samples = [...]}` or `{fourier = [[re, im], ...]}`"),
        ("… must be one period of sampled values (1-D array) or a dopplertof.codes.Code, got …", "a code is neither samples nor a `Code`", "one period of samples"),
        ("…: complex values are Fourier coefficients; pass dopplertof.codes.fourier(...)", "complex samples were given as a code", "`dopplertof.codes.fourier(...)`"),
        ("… must be one period of samples (1-D), got shape …; pick one row of a code table", "a code table was given where one code is needed", "one row (`{table = \"codes.npy\", row = 0}` in a file)"),
        ("…: a code table is K rows x N real samples, got … of shape …", "a code table file of another shape", "a K × N real array"),
        ("…: codes need N >= … finite samples per row, got shape …", "too few samples per code", "at least the number named"),
        ("…: a code table is a .npy or .npz file", "a code table of another format", "`.npy` or `.npz`"),
        ("…: holds arrays …; name the code table 'codes'", "an `.npz` with several arrays", "name the table `codes`"),
        ("…: 'fourier' must list [re, im] pairs, got …", "Fourier coefficients written otherwise", "`[[re, im], ...]`"),
        ("band_limited: the bandwidth passes no harmonic of the modulation", "a light bandwidth below the modulation frequency", "a bandwidth of at least f_g"),
        ("codes of … and … samples need a common grid of … > …", "two sampled codes whose lengths have a huge common multiple", "resample them to a common length"),
        ("Code: give exactly one of 'samples' or 'fourier'", "a code needs one description", "give one"),
        ("Code: 'samples' must be one period of N >= … values, got shape …", "too few samples", "at least the number named"),
        ("Code: 'samples' must be finite numbers", "NaN or infinite samples", "finite values"),
        ("Code: 'fourier' must hold c_0 ... c_M with 1 <= M <= …, got shape …", "too few or too many coefficients", "1 ≤ M ≤ the maximum named"),
        ("Code: 'fourier' coefficients must be finite", "NaN or infinite coefficients", "finite values"),
        ("Sensor: 'frames' must be a non-empty list of dopplertof.RawFrame, got …", "a sensor needs frames", "a list of `dt.RawFrame`"),
        ("Sensor: 'taps' must be one of …, got …", "a tap count the model does not have", "one of those named"),
        ("Sensor: 'noise' must be a dopplertof.sensors.Silicon, got …", "`noise` of another type", "a `Silicon`"),
        ("Sensor: frame … (…): its demodulation spans […, …]", "a demodulation code outside [−1, 1]", "scale the sensor code into [−1, 1]"),
        ("Sensor: frame … (…): a 4-tap pixel needs a demodulation without mean or harmonics at multiples of 4", "this code cannot be split over four taps", "another code, or 2 taps"),
        ("Sensor: frame … (…): …", "a frame the sensor cannot take (the message says why)", "fix the frame it names"),
        ("Sensor.raw: expected the … measurements of Sensor.cameras(), got shape …", "measurements of other cameras", "render with `sensor=` and pass `result.measurements`"),
        ("Sensor.read_out: unknown mode …; choose one of …", "an unknown read-out mode", "one of those named"),
        ("Sensor.read_out: 'seed' must be >= 0, got …", "a negative noise seed", "a whole number ≥ 0 (or a `numpy.random.SeedSequence`)"),
        ("Sensor.read_out: mode … needs a 2-tap pixel", "the mode reads differential taps", "`mode='raw'`"),
        ("Sensor.read_out: raw must have shape (…, …, ...), got …", "raw electrons of another shape", "pass `result.raw`"),
        ("Sensor.read_out: raw frames … hold no charge estimate", "the render stopped before these frames' window", "finish the render (`--resume`)"),
        ("RawFrame: give heterodyne (h=…) or heterodyne_hz (… Hz), not both", "two ways to give one offset", "give one"),
        ("the expected tap charge must be finite electrons", "a frame without samples (NaN)", "finish the render"),
        ("Silicon: … must be a number in (0, 1] or a table of (…, value) pairs, got …", "QE or contrast of another form", "a number or a table"),
        ("Silicon: … needs positive … and values in (0, 1], got …", "a table with bad entries", "positive wavelengths or frequencies, values in (0, 1]"),
        ("Silicon: … must list strictly increasing …, got …", "a table out of order", "sort it"),
        ("… is tabulated for … to … …, not … …", "a wavelength or frequency outside the silicon's table", "one inside the table, or extend it"),
        ("Silicon: … must be in (0, 1], got …", "a fraction out of range", "a value in (0, 1]"),
        ("Silicon.with_electrons_per_unit_s: give electrons_per_unit_s or radiance_unit, not both", "the light level was given twice", "give one of them"),
        ("sensor preset …: unknown silicon parameter(s) …", "a preset got a silicon parameter that does not exist", "the parameters of `Silicon`"),
        ("… cannot capture this schedule: …", "the chip cannot take these frames (frequency, phase step, integration time, frame count)", "change the frames as the message says"),
        ("rgb must have shape (..., 3), got shape …", "luminance of a non-RGB image", "an RGB image"),
        ("camera exposure must be a finite number > 0 s, got …", "a camera without exposure", "T in seconds"),
        ("camera g0 must be a finite number >= 0, got …", "a negative DC offset", "0 or more"),
        ("measurements_from_readout: a 1-tap pixel does not separate the modulated signal", "a 1-tap read-out gives no measurement", "a 2- or 4-tap sensor"),
        ("measurements_from_readout: dn must have shape (…, …, ...), got …", "digital numbers of another shape", "pass the read-out of this sensor"),
        ("measurements_from_readout: frames … demodulate with a code that is not antiperiodic", "taps 0 − 2 of a 4-tap pixel do not give this code's measurement", "an antiperiodic code"),
        ("… uses the sinusoid's closed form; got waveform(s) …", "the estimator models the sinusoid", "sinusoidal frames"),
        ("… needs every frame in one exposure window (same exposure_start)", "frames in several windows", "one window"),
        ("measurements must have shape (…, ...), got …", "as many measurements as frames are needed", "pass the sensor's measurements"),
        ("two_offset_velocity needs exactly two heterodyne offsets h that differ by whole beat cycles", "the two-offset estimator's frames", "two offsets a whole number of cycles apart"),
        ("two_capture_velocity needs homodyne frames (h = 0)", "two captures compare depth phases; heterodyne frames need the two-offset estimator", "use `two_offset_velocity`, or homodyne frames"),
        ("two_capture_velocity needs two captures of the same phases", "the frames are not two captures of one phase schedule, a constant interval apart", "give frames [:n/2] and [n/2:] with the same phases, and their exposure starts"),
        ("max_depth_m must be a finite number > 0, got …", "no depth bound", "metres"),
        ("a search to … m spans … wraps of … Hz; give max_depth_m", "the depth search is too long", "a smaller `max_depth_m`"),
        ("offset h=…: phases … deg do not give a quadrature", "the phases do not balance", "phases with Σ e^{2iψ} = 0 (0 and 90°; four at 90°; three at 120°)"),
        ("multifrequency_depth takes homodyne frames (h = 0)", "heterodyne frames given", "homodyne frames"),
        ("multifrequency_depth uses the sinusoid's phase", "other waveforms given", "sinusoidal frames"),
    ]),
    ("Sensor design", "`dopplertof design` and `dopplertof.design` (response records, bounds, gradients, sweeps).", [
        ("gradient: 'sensor' must be a dopplertof.Sensor, got …", "`sensor` of another type", "a `dt.Sensor`"),
        ("gradient: unknown objective …; choose one of …", "an unknown objective", "one of those named"),
        ("gradient: the … is infinite (or no pixel moves) everywhere; no gradient", "the bound is infinite on every pixel", "a sensor whose frames determine velocity, a scene that moves"),
        ("…: the record holds no frequency slopes; render it with record=dict(…", "frequency gradients need slopes", "render the record with `slopes=True`"),
        ("gradient: heterodyne of …: the record holds no first moments", "heterodyne gradients need first moments", "render the record with `doppler=True`"),
        ("gradient: a parameter is (kind, frame index), got …", "a parameter given otherwise", "`(\"modulation_frequency\", 0)`"),
        ("--record: give one per scene", "`--record` files and scenes are paired in order", "one `--record` per SCENE, or none"),
        ("--record: the record holds its render; … would render another (leave … out, or leave out --record)", "render options (`--spp`, `--resolution`, …) beside `--record`", "leave them out to sweep the record, or leave out `--record` to render anew"),
        ("--record …: rendered from …, not … (…); render the record of … (leave out --record)", "a record of another scene (or the same file changed since, or other `-D` values)", "render the record of this scene"),
        ("--samples applies to --dataset", "`--samples` counts a dataset's scenes", "add `--dataset CONFIG.toml`, or drop `--samples`"),
        ("give SCENE (one or more) or --dataset CONFIG.toml --samples N", "`dopplertof design` has no scene", "name scenes, or a dataset config and how many of its scenes"),
        ("give SCENE… or --dataset, not both", "the scenes come from files or from a dataset, not both", "drop one"),
        ("--dataset needs --samples N", "how many of the dataset's scenes to design over", "add `--samples N`"),
        ("--resolution …: dataset scenes are square; give one number", "dataset scenes take one film size", "give `N`"),
        ("…: the record holds no window slopes; render it with record=dict(", "exposure and start gradients need the record's window slopes", "record with `record=dict(window_slopes=True)`"),
        ("luminance_slopes of shape … do not match the luminance", "a record's arrays disagree (a damaged or hand-made file)", "render the record again"),
        ("record: window_slopes needs the single-path tracer", "the paired tracers record through probe cameras, which give no window slopes", "use correlation replay or none with antithetic or uniform sampling"),
        ("design: no record (give at least one scene)", "a design over no scene", "give at least one record or scene"),
        ("gradient: unknown parameter …; choose one of …", "an unknown parameter kind", "one of those named"),
        ("gradient: parameter (…, …): the sensor has frames 0 to …", "a frame index out of range", "an existing frame"),
        ("gradient: parameter ('heterodyne', …): the … needs second moments", "the record cannot give this gradient", "differentiate the raw frames' heterodyne"),
        ("gradient: parameter (…, …): code gradients are with respect to Fourier coefficients", "a sampled code cannot be differentiated", "give the frame's codes with `dopplertof.codes.fourier`"),
        ("…: needs a response record (dopplertof.render(..., record=dict(doppler=True)) or its .record), got …", "no record given", "render with `record=`"),
        ("…: the record holds no first moments; render it with record=dict(doppler=True, ...)", "velocity derivatives need first moments", "render the record with `doppler=True`"),
        ("crb: 'sensor' must be a dopplertof.Sensor, got …", "`sensor` of another type", "a `dt.Sensor`"),
        ("achieved_rmse: 'draws' must be an integer >= 2, got …", "too few read-outs", "2 or more"),
        ("record must be True, a dict of RecordSpec fields or a dopplertof.design.RecordSpec, got …", "`record=` of another type", "True, a dict or a `RecordSpec`"),
        ("record: unknown key(s) …", "a record key that does not exist", "the keys named"),
        ("record: 'band_hz' must be (lowest, highest) in Hz, got …", "a band of another form", "two frequencies in Hz"),
        ("record: 'band_hz' must satisfy 0 < lowest <= highest <= … Hz, got …", "a band out of range", "a band within the range named"),
        ("record: 'step_hz' must be > 0 Hz, got …", "no frequency step", "Hz > 0"),
        ("record: no multiple of step_hz=… Hz lies in band_hz=…", "an empty frequency grid", "a finer step or a wider band"),
        ("record: band_hz=… at step_hz=… Hz is … frequencies, more than …", "too many frequencies", "a coarser step or a narrower band"),
        ("record: 'beats' must be a sequence of beat cycles per exposure, got …", "beats of another form", "a list of numbers"),
        ("record: 'beats' must hold 1 to … values, got …", "too few or too many beats", "a count in the range named"),
        ("record: 'beats' lists a value twice: …", "a repeated beat", "each beat once"),
        ("record: 'beats' must be within +-…, got …", "a beat out of range", "beats within the range named"),
        ("record: 'cameras_per_render' must be >= 1, got …", "no cameras per render", "1 or more"),
        ("…: its exposure window (start … s, … s) was not recorded", "a camera in a window the record lacks", "record that window"),
        ("…: needs the beat … cycles per exposure, which the record does not hold", "a beat the record lacks", "declare it in the record's beats"),
        ("…: needs the frequency … Hz, which the record does not hold", "a frequency off the record's grid", "a frequency on the grid, or record it"),
        ("record: … frequencies x … beats x … window(s) on a …x… film need about … GiB", "the record does not fit in memory", "a coarser `step_hz`, a narrower band or fewer beats"),
        ("…: the full-waveform model (low_pass=False) has unbounded harmonics", "a record reads out low-pass cameras only", "`low_pass=True`"),
        ("…: the … waveform has unbounded harmonics", "square-like waveforms cannot be read from a record", "the sinusoid or a band-limited code (`light_bandwidth`)"),
        ("…: two sampled codes correlate to unbounded harmonics", "sampled codes need a band limit", "give the camera a `light_bandwidth` within the record's band"),
        ("evaluate: 'record' must be a dopplertof.design.Record, got …", "`record` of another type", "a `Record`"),
        ("write_record: 'record' must be a dopplertof.design.Record (dopplertof.render(..., record=...).record), got …", "the render's result (or another object) was given instead of its record", "pass `result.record`"),
        ("evaluate: 'sensor' must be a dopplertof.Sensor or a list of dopplertof.Camera, got …", "`sensor` of another type", "a sensor or cameras"),
        ("format …, expected …", "a record file of another format version", "render the record again"),
        ("arrays of shape … and … do not match the record's grid …", "a damaged record file", "render the record again"),
        ("… of shape … do not match the phasors …", "a damaged record file", "render the record again"),
        ("…: not a dopplertof response record (…)", "the file is not a record", "give a file of `dt.io.write_record`"),
        ("--sweep …: expected KEY=LO:HI:N", "`--sweep` of another form", "`modulation_frequency=10e6:100e6:10`"),
        ("--sweep …: unknown key …; choose one of …", "a key that cannot be swept", "one of those named"),
        ("--sweep …: needs finite LO <= HI and N >= 1", "an empty or reversed sweep", "LO ≤ HI, N ≥ 1"),
        ("the sweep has … points, more than …; use fewer values", "too many combinations", "fewer values"),
        ("unknown objective …; choose one of …", "an unknown objective", "one of those named"),
        ("--optimize: choose keys among …, got …", "a key that cannot be optimised", "one of those named"),
        ("frame …: a record's frequencies are whole Hz, got … Hz (…); give the sensor whole-Hz frequencies (a sensor file's [[frames]] modulation_frequency)", "a frame's frequency (or a harmonic of it) has a fraction of a Hz: the `kinect-v2` preset's derived frequencies do", "a sensor file whose frames give whole-Hz frequencies"),
    ]),
    ("Oracles", "`dopplertof.oracles`: the independent references the tests and benchmarks compare renders with.", [
        ("baked_scene_dict: … is a moving sensor or emitter; only shapes may move", "the outline oracle bakes moving shapes only", "keep the camera and lights static"),
        ("baked_scene_dict: … has motion …; only keyframes are supported", "the oracle interpolates keyframes itself, not parametric motion", "describe the motion as keyframes"),
        ("baked_scene_dict: the keys of … rotate or scale; only translations are supported", "the oracle's interpolation is translation only", "translating keyframes"),
        ("scene_dict: the outline oracle needs a perspective (pinhole) camera", "its camera rays are those of a pinhole", "a `perspective` sensor"),
        ("scene_dict: the outline oracle needs point lights only", "its paths are camera, surface, light", "point lights"),
        ("moving_outline_pixels: 'grid' must be >= 1", "the sub-pixel grid that finds outline pixels is empty", "1 or more"),
        ("direct_light_pixels: cameras must be low-pass and share one exposure window", "the oracle integrates one window with the low-pass weights", "low-pass cameras of one window"),
        ("direct_light_pixels: … must be >= …, got …", "a count (replicates, strata, samples) below its minimum", "the minimum named"),
        ("direct_light_pixels: 'pixels' must be (x, y) integer pairs on the …x… film", "pixels off the film or not integer pairs", "pixels inside the film"),
    ]),
    ("Backend", "Starting Mitsuba and Dr.Jit (see [installation](installation.md)).", [
        ("unsupported Mitsuba variant …; choose one of …", "`--variant` names a variant dopplertof does not support", "`llvm_ad_rgb` runs on any CPU with libLLVM ≥ 16"),
        ("the … integrator renders in the Mitsuba variants …, not in … (no scalar or spectral variant)", "`mi.load_dict`/`mi.load_file` of a scene with the `dopplertof` integrator under a scalar or spectral variant", "`mi.set_variant('llvm_ad_rgb')` (or `cuda_ad_rgb`) before loading"),
        ("…=… is not a file; point it at libLLVM >= …", "`DRJIT_LIBLLVM_PATH` names no file", "point it at the library or unset it"),
        ("…=… is LLVM …, but Dr.Jit needs libLLVM >= …", "`DRJIT_LIBLLVM_PATH` names an LLVM older than 16", "point it at a newer one or unset it"),
        ("Dr.Jit loaded libLLVM … (…), which aborts on dopplertof's kernels", "an LLVM 14 or 15 was loaded", "install libLLVM ≥ 16 as the message says"),
        ("no Dr.Jit backend works; …", "neither LLVM nor CUDA starts", "install libLLVM ≥ 16 (`sudo apt-get install libllvm19`)"),
        ("cannot start Mitsuba variant … (…); …", "the variant asked for does not start here", "another variant; the message says why"),
    ]),
    ("Image files", "Reading and writing images and records (`dt.io`, `dopplertof reconstruct`).", [
        ("an image with … channels needs explicit channel names", "EXR channels are named", "pass `channels=[...]`"),
        ("unsupported image suffix … in '…'; use '.exr' or '.npy'", "an image format dopplertof does not write", "`.exr` or `.npy` (PNG pictures: `dopplertof.viz`)"),
        ("image must have shape (H, W) or (H, W, C), got shape …", "not an image", "a 2-D or 3-D array"),
        ("image must not be empty, got shape …", "an empty array", "at least one pixel"),
        ("image must be real-valued, got dtype …", "a complex or non-numeric array", "real values"),
        ("got … channel names … for an image with … channel(s)", "as many names as channels are needed", "one name per channel"),
        ("channel names must be unique, got …", "two channels share a name", "distinct names"),
        ("channel names must be non-empty strings, got …", "an empty channel name", "non-empty strings"),
        ("OpenEXR file '…' has no channels", "an empty EXR file", "write the image again"),
        ("channels of '…' have different shapes …; use read_exr_channels", "an EXR whose channels differ in size", "`read_exr_channels`"),
        ("cannot read '…' as an OpenEXR image: …", "the file is not an EXR image or is damaged", "write it again"),
        ("cannot read '…' as a .npy array: …", "the file is not a `.npy` array or is damaged", "write it again"),
        ("cannot read '…' as …: it is not one (it starts with …)", "a file that is not a `.npy` array or a `.npz` record at all (text, another format)", "give the file the render or `design` wrote"),
        ("cannot read '…' as JSON: …", "the file is not JSON or is damaged", "write it again"),
        ("cannot read '…' as a response record: …", "the file is not a response record", "give a file of `dt.io.write_record`"),
        ("expected a '…' file, got '…'", "a picture path with another suffix", "the suffix named"),
        ("signed maps must have shape (H, W), got shape …", "a signed map with channels", "one channel, or a luminance"),
        ("vmax must be finite and > 0, got …", "no colour range", "a positive range"),
        ("image must have shape (H, W) or (H, W, 3), got shape …", "not an image", "a 2-D or RGB array"),
        ("exposure must be finite and > 0, got …", "a picture exposure of 0 or below", "a positive factor"),
        ("picture must be uint8, got dtype …; use to_srgb8 or signed_to_rgb8", "a picture of floats", "convert it first"),
        ("picture must have shape (H, W), (H, W, 3) or (H, W, 4), got shape …", "not a picture", "grey, RGB or RGBA"),
        ("picture must not be empty, got shape …", "an empty picture", "at least one pixel"),
        ("images must contain at least one panel, got …", "nothing to show", "one panel or more"),
        ("x must be a non-empty 1-D array, got shape …", "a plot without x values", "a 1-D array"),
        ("curves must contain at least one curve, got …", "nothing to plot", "one curve or more"),
        ("curve …: y has shape …, x has shape …", "x and y differ in length", "equal lengths"),
        ("curve … must be (y, yerr), got … items", "a curve with errors of another form", "`(y, yerr)`"),
        ("curve …: yerr has shape …, x has shape …", "errors and x differ in length", "equal lengths"),
        ("curve …: yerr must be >= 0, got minimum …", "a negative error bar", "errors ≥ 0"),
        ("fps must be finite and > 0, got …", "a GIF rate of 0 or below", "frames per second"),
        ("fps must be >= …: a GIF frame lasts at most … s, got fps=…", "a GIF cannot hold a frame that long", "a higher rate"),
        ("frames must contain at least one frame, got 0", "an empty GIF", "one frame or more"),
        ("frame … must be uint8, got dtype …", "a GIF frame of floats", "convert it first"),
        ("frame … must have shape (H, W, 3), got …", "a GIF frame that is not RGB", "RGB frames"),
        ("frame … has shape …, frame 0 has shape …", "GIF frames of different sizes", "one size"),
        ("unknown matplotlib colour map …", "no colour map of that name", "a matplotlib colour map name"),
    ]),
    ("Scene files", "A Mitsuba XML scene that the loader refuses (see [scene format](scene-format.md)): the message names the file, the element and the property.", [
        ("…: <… name=…> is not an integer, float, boolean or string property", "a property of another type where a number, boolean or string is needed", "write it as `<float>`, `<integer>`, `<boolean>` or `<string>`"),
        ("…: <… name=… value=…>: expected …", "a property value that does not parse", "the type the message names"),
        ("…: … is … m/s, at or above the speed of light", "a motion faster than light", "check the units: m/s"),
        ("…: expected a 4x4 matrix, got shape …", "a keyframe matrix of another shape", "a 4 × 4 matrix"),
        ("…: transform has non-finite entries (NaN or inf): …", "a transform with NaN or inf", "finite values"),
        ("…: translation … m is beyond the … m any coordinate may reach", "a position too far for float32 hit points", "keep the scene within the limit named"),
        ("…: projective matrices cannot be rigid motion keys", "a keyframe with a projective row", "Translate·Rotate·Scale"),
        ("…: degenerate (zero-scale) transform", "a zero scale", "a non-zero scale"),
        ("…: reflections cannot be interpolated as rigid motion", "a keyframe with a negative determinant", "no mirroring in motion keys"),
        ("…: transform has shear; motion keys must be Translate·Rotate·Scale", "a sheared keyframe", "Translate·Rotate·Scale with a per-axis scale"),
        ("…: at least one keyframe is needed", "an empty `<animation>`", "give keyframes"),
        ("…: … key times but … matrices", "times and transforms do not pair up", "one time per transform"),
        ("…: keyframe times must be finite numbers, got …", "a keyframe time that is not a number", "seconds"),
        ("…: keyframe times must be strictly increasing, got …", "keyframe times out of order", "sort them"),
        ("…: pivot … m is beyond the … m any coordinate may reach", "a pivot too far away", "a pivot within the limit"),
        ("…: … must be 3 finite numbers, got …", "a vector of another length or with NaN", "3 numbers"),
        ("…: emitter … (…): … …; emitted radiance, intensity and irradiance must be finite and >= 0", "a negative or infinite emitter", "finite values ≥ 0"),
        ("…: the scene has no sensor", "nothing to render from", "add a `<sensor>`"),
        ("traversal must be one of …, got …", "an unknown traversal", "one of those named"),
        ("traversal='tree' traces inside dr.switch (OptiX direct callables) and is not supported on …", "the tree traversal does not run on the GPU", "`atlas` (the tree without `dr.switch`), `per-body` or `auto`"),
        ("traversal='slices' traces one scene per member in a kernel, which OptiX does not allow yet on …; use 'atlas' or 'auto'", "one scene per instant runs on the CPU only so far (a CUDA kernel may trace one OptiX pipeline)", "`atlas` or `auto` on the GPU, `slices` on an `llvm_*` variant"),
        ("moving body … cannot be copied for traversal='slices' (it was not built by dopplertof.load_scene)", "a `Body` made by hand has no way to load its shapes again for the member scenes", "build the scene with `dopplertof.load_scene` (or `scenes.build`)"),
        ("a moving shape (…) has neither vertex positions nor a to_world to place it by", "a moving shape type one scene per instant cannot place (neither a mesh nor a shape with a `to_world`)", "a mesh, or `traversal='auto'`"),
        ("traversal='atlas' cannot hold …; use 'per-body' or 'auto'", "a moving body holds a shape the body atlas cannot copy into its cell (an instance, a curve); the message names the body and the shape", "`per-body`, or `auto` (which takes the per-body loop for such a scene)"),
        ("the body atlas cannot hold …", "`BodyAtlas.build` was given a body whose shape it cannot copy (an instance, a curve)", "check `BodyAtlas.unsupported` first, or use the per-body traversal"),
        ("time window must be finite with t0 <= t1, got […, …] s", "an empty or reversed window", "t0 ≤ t1"),
        ("load_scene expects a file path or a dict, got …", "the API's `load_scene` got something else", "a path or a scene dict"),
        ("dataset indices must be integers or slices, not …", "`dt.dataset.open(...)[i]` with a float, a string or a bool", "an integer, or a slice for a list of samples"),
        ("film_resolution must be a positive int or a (width, height) pair of them, got …", "a film size of another form", "`64` or `(128, 96)`"),
        ("<dict>: $name substitutions … apply to scene files only", "parameters given for a scene dict", "put the values in the dict"),
        ("<dict>: a scene dict needs 'type': 'scene'", "the dict is not a scene", "`{\"type\": \"scene\", ...}`"),
        ("<dict>: the scene has no sensor", "nothing to render from", "add a sensor"),
        ("…: scene file not found", "the path names no file", "check the path"),
        ("…: malformed XML (…)", "the file does not parse as XML", "fix the XML at the place named"),
        ("…: include cycle (…)", "files include each other", "break the cycle"),
        ("…: version … mixes the Mitsuba 0.6 and 3 formats", "a file with constructs of both formats", "convert it to one format"),
        ("…: unknown parameter… …; the scene's parameters: …", "`-D` or a keyword names no `$name` of the file", "the parameters listed"),
        ("…: unresolved parameter … in <…", "a `$name` without a value or `<default>`", "`-D name=value` or a `<default>`"),
        ("…: the root element must be <scene>, got <…>", "not a scene file", "a file whose root is `<scene>`"),
        ("…: <film> has …, a crop window of its own size; a new film size (--resolution, film_resolution=) would crop something else: remove the crop window or keep the size", "`--resolution` (`film_resolution=`) cannot change a film with a crop window, which is in the film's own pixels", "remove the crop window from the film, or leave out the new size"),
        ("…: an <animation> inside <… type=\"…\"> (…): …", "an `<animation>` nested where nothing moves", "animate the top-level shape, emitter or sensor (for a shapegroup, its `instance`)"),
        ("…: the scene has no <sensor>", "nothing to render from", "add a `<sensor>`"),
        ("…: the scene has … sensors; dopplertof renders one", "several sensors", "remove the others"),
        ("…: the film's pixel_format is …; dopplertof writes the intensity as RGB", "an hdrfilm with `pixel_format` xyz, luminance or with alpha (it was ignored)", "remove `pixel_format` or give `rgb`; `coverage.exr` holds what alpha would"),
        ("…: the sensor is … (…), which dopplertof does not render; …", "an irradiancemeter, or a batch sensor (whose cameras' ground truth would be in the batch's frame)", "what the message says: a radiancemeter or a perspective camera looking at the shape; each camera of a batch as a scene of its own"),
        ("…: the sensor's shutter_open=… and shutter_close=… s must be finite", "a shutter time that is not a number", "seconds"),
        ("…: the sensor's shutter_open and shutter_close are both … s, a shutter that never opens", "an empty shutter interval", "`shutter_close > shutter_open`, or neither"),
        ("…: the film must be at least 1x1 pixels, got …x…", "an empty film", "a positive size"),
        ("…: a scene with moving bodies cannot use shape type … on …", "a shape the GPU pipeline of moving bodies does not cover", "a mesh, or the llvm variant"),
        ("…: expected numbers, got …", "a value that is not numbers", "numbers"),
        ("…: expected 1 or 3 numbers in value=…", "a vector of another length", "1 or 3 numbers"),
        ("…: expected a 4x4 transform, got shape …", "a transform of another shape", "a 4 × 4 matrix"),
        ("…: rotate needs angle=\"degrees\"", "a rotation without angle", "`angle=\"90\"`"),
        ("…: rotate needs a non-zero axis (x, y, z)", "a rotation about no axis", "a non-zero axis"),
        ("…: matrix needs 9 or 16 numbers, got …", "a matrix of another size", "9 or 16 numbers"),
        ("…: unknown transform operation", "an element inside `<transform>` that is not a transform", "translate, rotate, scale, matrix, lookat"),
        ("…: only <animation name=\"to_world\"> is supported, got name=…", "an animation of another property", "`name=\"to_world\"`"),
        ("…: <animation> may only contain <transform time=\"...\">, found <…>", "other elements in an animation", "keyframes only"),
        ("…: <transform> needs a time=\"seconds\" attribute", "a keyframe without time", "`time=\"0.001\"`"),
        ("…: keyframe time … is not a number", "a keyframe time that does not parse", "seconds"),
        ("…: a keyframe is a pair (time_s, transform), got …", "a dict keyframe with more or fewer than two entries", "`(time_s, transform)` per key"),
        ("…: <animation> has no keyframes", "an empty animation", "give keyframes"),
        ("…: more than one <animation>", "two animations on one element", "merge them"),
        ("…: has both <transform name=\"to_world\"> and <animation>; keep one", "a static and a keyed placement", "keep one"),
        ("…: keyframed motion replaces 'to_world'; remove one of them", "a dict with both", "keep one"),
        ("…: has both a position and an <animation>", "a light placed twice", "remove the position"),
        ("…: an emitter of type … cannot move; moving lights are … emitters, or area emitters on a moving shape", "environment and directional emitters stay put", "point or spot emitters, or area emitters on a moving shape"),
        ("…: an emitter of type … inside the <sensor> would move with the camera, and it cannot move; the lights a camera carries are … emitters", "an area, environment or directional emitter inside the `<sensor>`", "a point or spot emitter in the sensor, or the emitter at the top level"),
        ("…: a light attached to a camera whose motion is a … on top of a to_world is not supported", "this camera motion cannot carry a light", "keyframes that include the placement"),
        ("…: …carries a sensor; a camera moves by its own <animation> (XML) or 'motion' (dict)", "a sensor inside a moving shape", "animate the sensor itself"),
        ("…: … has a motion that scales (its keys carry a scale", "a scaling camera or light motion (a constant scale in its keys too: an orthographic sensor's extent)", "translate and rotate only; an orthographic sensor cannot move"),
        ("…: moving body … carries an emitter and its motion's keys scale the axes differently; give the shape its own to_world and a parametric motion, or keys that scale every axis equally", "an emitter on a body whose keyframes scale it per axis", "a parametric motion over the shape's own `to_world`, or keys with one scale on every axis"),
        ("…: the sensor is inside a participating medium; media are not supported", "media", "remove the medium"),
        ("…: …shape … has a participating medium; media are not supported", "media", "remove the `<medium>` or render with stock Mitsuba's volpath"),
        ("…: …shape … has a position or size that is not finite (NaN or inf in its transform or its parameters); it would render as nothing", "a NaN or infinite value in a shape's transform, radius or other size (Mitsuba renders such a shape as nothing, silently)", "fix the value the message's shape holds"),
        ("…: a <…> outside the <sensor> is ignored by Mitsuba; move it into the <sensor>", "a `<sampler>` or `<film>` at the scene's top level, which Mitsuba ignores without a word", "move it into the `<sensor>`"),
        ("…: a second <integrator>; a scene has one (Mitsuba refuses two as well)", "two `<integrator>` elements; the first would be dropped", "keep one"),
        ("…: a second integrator; a scene has one (Mitsuba refuses two as well)", "two integrator entries in a scene dict", "keep one"),
        ("…: a blackbody spectrum needs a spectral Mitsuba variant, and dopplertof renders in RGB (or mono)", "a `<spectrum type=\"blackbody\">` (Mitsuba implements it in spectral variants only; the render would fail part way)", "give the emitter an `<rgb>` value"),
        ("…: 'motion' must be a Motion or a dict with type 'keyframes' or 'parametric', got …", "a dict motion of another form", "one of the two types"),
        ("…: unknown motion parameter(s) … for type …", "a motion key that does not exist", "the keys of that motion type"),
        ("…: … must be a …, got …", "a Mitsuba 0.6 property of the wrong type", "the type named"),
        ("…: 'antithetic_shifts' is empty", "no shifts", "give shifts or remove the property"),
        ("…: 'antithetic_shifts' must be whitespace-separated numbers, got …", "shifts that do not parse", "`0.25 0.5 0.75`"),
        ("…: 'antithetic_shifts_number' must be >= 0, got …", "a negative count", "0 or more"),
        ("…: antithetic with … shifts needs the evenly spaced set", "shifts the renderer does not take", "i/N, i = 1..N−1"),
        ("…: antithetic_mirror pairs 2 times", "a mirror with more shifts", "remove `antithetic_shifts_number`"),
        ("…: antithetic_mirror takes one shift", "a mirror with several shifts", "one shift"),
        ("…: 'antithetic_shifts'=… contradicts 'antithetic_shifts_number'=…", "two ways to give the shifts disagree", "give one"),
        ("…: 'low_frequency_component_only'=false was ignored by the original", "the original's misspelt key decided", "set `low_srequency_component_only` to choose"),
        ("…: unknown Mitsuba 0.6 dopplertofpath parameter …", "a 0.6 integrator key that does not exist", "the keys of the original (scene format page)"),
        ("…: …=… is not supported: …", "a 0.6 value this renderer does not reproduce (the message says why)", "another value"),
        ("…: unknown time_sampling_mode …; choose one of …", "a 0.6 time sampling that does not exist", "one of those named"),
        ("…: spatial_correlation_mode 'mis' (the original's experimental five-path mode) has no equivalent here", "an experimental mode", "ray_position, ray_sampler or ray_adaptive"),
        ("…: unknown spatial_correlation_mode …; choose one of …", "a 0.6 correlation that does not exist", "one of those named"),
        ("…: … pairs 2 times (the original used only the first two), got …", "more times than the mode pairs", "2"),
        ("…: analytic time sampling needs a paired spatial_correlation_mode", "analytic sampling without a partner", "ray_position, ray_sampler or ray_adaptive"),
        ("…: the D-ToF integrator needs shutterOpen=0 and shutterClose=time=…", "a 0.6 shutter that disagrees with the exposure", "shutterOpen=0, shutterClose = time"),
        ("…: <srgb name=…>: expected #rrggbb or 1 or 3 numbers, got …", "a colour that does not parse", "`#rrggbb` or numbers"),
        ("…: strictNormals=true differs from Mitsuba 3", "Mitsuba 3 shades otherwise", "the change the message names"),
        ("…: roughdiffuse (Oren-Nayar) has no Mitsuba 3 equivalent unless alpha is 0", "a BSDF Mitsuba 3 lacks", "alpha 0 (diffuse) or another BSDF"),
        ("…: film pixelFormat … has no Mitsuba 3 equivalent", "a 0.6 pixel format", "one of those named"),
    ]),
]

# Messages composed away from the call that raises them (the reasons of
# dopplertof.reconstruct.identify, returned as text and raised by its callers): catalogued by
# hand, so the source scan does not see them.
COMPOSED_ELSEWHERE = ("all cameras have the same heterodyne ratio h = …", "the cameras … cannot determine velocity",
                      "'max_depth' must be >= 1 or -1 (unbounded), got …",  # a setting's rule (settings.py)
                      "…: a blackbody spectrum needs a spectral Mitsuba variant, and dopplertof renders in RGB (or mono)")  # loader.BLACKBODY_REFUSAL

def _template(node, constants=None) -> str:
    """A message expression as its template: literal text kept (and the module's string
    constants, ``constants``: name → text), every value ``…``."""
    constants = constants or {}
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        text = node.value
    elif isinstance(node, ast.JoinedStr):
        text = "".join(part.value if isinstance(part, ast.Constant) else "…" for part in node.values)
    elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        text = _template(node.left, constants) + _template(node.right, constants)
    elif isinstance(node, ast.Name) and node.id in constants:
        text = constants[node.id]
    else:
        text = "…"
    # An optional prefix stuck to a value ("{where}{name!r} must be") reads as one value.
    return re.sub("…+", "…", " ".join(text.split()))


def _says_something(template: str) -> bool:
    """Whether a template has words of its own: all literal, or two words or more
    (``…: …`` and ``panel …: …`` pass another message on)."""
    return "…" not in template or len(re.findall(r"[A-Za-z]{3,}", template)) >= 2


def source_messages(package: Path) -> list[tuple[str, int, str]]:
    """(file, line, template) of every message of :data:`MESSAGE_CALLS` in the package's
    source, and of every ``click.echo("error: …")`` line. A message kept in a module-level
    constant is read from it; one built elsewhere and passed in a variable is not seen
    (:data:`COMPOSED_ELSEWHERE`).

    Parameters
    ----------
    package : Path
        The ``dopplertof`` package folder.

    Returns
    -------
    list of tuple of (str, int, str)
        Templates without words of their own (messages passed on) are left out.
    """
    found = []
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package).as_posix()
        tree = ast.parse(path.read_text(encoding="utf-8"))
        constants = {
            target.id: statement.value.value
            for statement in tree.body
            if isinstance(statement, ast.Assign) and isinstance(statement.value, ast.Constant) and isinstance(statement.value.value, str)
            for target in statement.targets
            if isinstance(target, ast.Name)
        }
        for node in ast.walk(tree):
            if not (isinstance(node, ast.Call) and node.args):
                continue
            template = _template(node.args[0], constants)
            if isinstance(node.func, ast.Name) and node.func.id in MESSAGE_CALLS:
                pass
            elif ast.unparse(node.func) == "click.echo" and template.startswith(_PRINTED):
                template = template[len(_PRINTED) :]  # a line a command prints itself
            else:
                continue
            if _says_something(template):
                found.append((relative, node.lineno, template))
    return sorted(found)


def unused_entries(messages, topics=TOPICS) -> list[str]:
    """The entries of ``topics`` that match none of ``messages`` (a message reworded or gone),
    but those of :data:`COMPOSED_ELSEWHERE`.

    Parameters
    ----------
    messages : iterable of tuple of (str, int, str)
        As :func:`source_messages` gives them.
    topics : list, default :data:`TOPICS`

    Returns
    -------
    list of str
    """
    templates = [template for _, _, template in messages]
    prefixes = [entry[0] for _, _, entries in topics for entry in entries if entry[0] not in COMPOSED_ELSEWHERE]
    return [p for p in prefixes if not any(t.startswith(p) for t in templates)]


def uncatalogued(messages, topics=TOPICS) -> list[str]:
    """The messages that no entry of ``topics`` matches (an entry matches the templates
    that start with its own), as ``file:line: template``.

    Parameters
    ----------
    messages : iterable of tuple of (str, int, str)
        As :func:`source_messages` gives them.
    topics : list, default :data:`TOPICS`

    Returns
    -------
    list of str
    """
    prefixes = [entry[0] for _, _, entries in topics for entry in entries]
    return [f"{file}:{line}: {template}" for file, line, template in messages if not any(template.startswith(p) for p in prefixes)]


def entry_for(message: str, topics=TOPICS):
    """The entry of a message as a command prints it (values filled in, ``error:`` left
    out): the most specific entry whose template the message, or the message after a
    ``where: `` prefix that a caller added (a scene's name, a file), starts with.

    Parameters
    ----------
    message : str
    topics : list, default :data:`TOPICS`

    Returns
    -------
    tuple of (str, str, str) or None
        (template, what it means, what to do); None where no entry matches.
    """
    message = " ".join(message.split())
    tails = [message] + [message[match.end() :] for match in re.finditer(": ", message)]
    matches = []
    for _, _, entries in topics:
        for entry in entries:
            pattern = ".*?".join(re.escape(part) for part in entry[0].split("…"))
            if any(re.match(pattern, tail) for tail in tails):
                matches.append(entry)
    return max(matches, key=lambda entry: len(entry[0].replace("…", "")), default=None)


def markdown(topics=TOPICS) -> str:
    """The catalogue as MyST Markdown: a section and a table per topic.

    Parameters
    ----------
    topics : list, default :data:`TOPICS`

    Returns
    -------
    str
    """
    lines = []
    for title, intro, entries in topics:
        lines += [f"### {title}", "", intro, "", "| message (… stands for a value) | what it means | what to do |", "|---|---|---|"]
        for message, means, fix in entries:
            cells = [f"`{message}`", means, fix]
            lines.append("| " + " | ".join(cell.replace("|", r"\|") for cell in cells) + " |")
        lines.append("")
    return "\n".join(lines)
