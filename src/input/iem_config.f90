!> Validated run configuration: what the namelist says, in types that travel together.
module iem_config
  use iem_kinds, only: wp, i8
  implicit none
  private
  public :: config_t, run_config_t, geometry_config_t, material_config_t
  public :: node_set_spec_t, time_function_spec_t, bc_config_t, load_config_t
  public :: damping_config_t, probe_config_t, static_config_t, initial_config_t
  public :: shape_config_t
  public :: name_len, path_len

  integer, parameter :: name_len = 64, path_len = 1024

  !> Run control (&run).
  type :: run_config_t
    character(len=16) :: analysis = 'dynamic'
    !> Time integrator of a dynamic run: 'rk4' or 'verlet' (velocity Verlet).
    character(len=16) :: integrator = 'rk4'
    real(wp) :: t_end = 0.0_wp
    real(wp) :: dt = 0.0_wp
    real(wp) :: dt_safety = 0.9_wp
    real(wp) :: output_interval = 0.0_wp
    real(wp) :: history_interval = 0.0_wp
    real(wp) :: progress_interval = 10.0_wp
    !> Guards of a dynamic run: relative energy-balance error that warns, and that stops the
    !> run (0: off); steps between checks for non-finite values and of the energy balance.
    real(wp) :: energy_warn = 0.05_wp, energy_stop = 0.5_wp
    integer :: check_interval = 10
    !> Accept a given dt above the stability limit (with a warning) instead of refusing it.
    logical :: allow_unstable_dt = .false.
    !> Checkpoints: simulated time between them (0: only on SIGTERM/SIGUSR1), the file
    !> ('' : output_file with the extension .chk), and the checkpoint to continue from.
    real(wp) :: checkpoint_interval = 0.0_wp
    character(len=path_len) :: checkpoint_file = ''
    character(len=path_len) :: restart = ''
    character(len=path_len) :: output_file = 'iem_out.h5'
    logical :: overwrite = .false.
    !> Recompute the partition at the top of this step (the bisection with the nodes of the
    !> left half of the grid ten times heavier) and move the state with it: the migration
    !> that load balancing uses, exposed to test it (0: never).
    integer :: repartition_step = 0
    !> Load balancing: every balance_interval steps (0: never) the ranks compare their
    !> computing time since the last look, and when the slowest exceeds the mean by more than
    !> balance_tolerance (a fraction) the partition is recomputed with each rank's part in
    !> proportion to its measured speed (nodes per second of computing).
    integer :: balance_interval = 0
    real(wp) :: balance_tolerance = 0.05_wp
  end type run_config_t

  !> The background grid of rectangular cells and what fills it (&geometry): the rectangle
  !> [0, length] x [0, height] cut into nx x ny cells, filled with the background material,
  !> then an optional cell map from an image, then the &shape groups in order (docs/model.md).
  type :: geometry_config_t
    real(wp) :: length = 0.0_wp, height = 0.0_wp, thickness = 1.0_wp
    integer :: nx = 0, ny = 0
    real(wp) :: cell_size = 0.0_wp
    character(len=8) :: plane = 'stress'
    !> Cell law: 'paper' (the paper's 12 springs) or 'bending' (bending-corrected cell).
    character(len=8) :: cell = 'paper'
    !> What fills the grid before the image and the shapes: a material name or 'void'
    !> ('': the first material); resolved to background_id (0: void, k: materials(k)).
    character(len=name_len) :: background = ''
    integer :: background_id = 1
    !> Cell map: a PBM/PGM image (one pixel a cell, row 1 at the top), its grey levels and the
    !> material ('void' or a name) each level gives; resolved to image_material_ids.
    character(len=path_len) :: image = ''
    integer, allocatable :: image_levels(:)
    character(len=name_len), allocatable :: image_materials(:)
    integer, allocatable :: image_material_ids(:)
    !> A body in several pieces: 'warn' (log a warning), 'allow' (log it) or 'one' (refuse).
    character(len=8) :: pieces = 'warn'
  end type geometry_config_t

  !> One shape (&shape, repeatable; later shapes win): a rectangle box = x0, x1, y0, y1, a
  !> circle (center, radius) or a polygon (points(2, n), n >= 3), giving its material to the
  !> cells whose centre it holds (material = 'void': removing them); material_id resolved
  !> (0: void, k: materials(k)).
  type :: shape_config_t
    character(len=name_len) :: name = ''
    character(len=12) :: kind = ''
    real(wp) :: box(4) = 0.0_wp
    real(wp) :: center(2) = 0.0_wp, radius = 0.0_wp
    real(wp), allocatable :: points(:, :)
    character(len=name_len) :: material = ''
    integer :: material_id = 0
    !> material = 'crack': the shape pre-cuts the cells whose centre it holds (every spring
    !> failed at the start) and leaves their material as it is.
    logical :: crack = .false.
  end type shape_config_t

  !> One material (&material, repeatable with distinct names): linear elastic, optionally
  !> with nonlinear springs.
  type :: material_config_t
    !> Name that shapes and the image refer to ('' allowed when there is one material).
    character(len=name_len) :: name = ''
    real(wp) :: young = 0.0_wp, poisson = 0.0_wp, density = 0.0_wp
    !> Nonlinear (hyperbolic, Masing) springs, with the continuum strengths (Pa) that set
    !> each spring kind's reference strain (docs/nonlinear.md), and the reversal points kept
    !> per spring.
    logical :: nonlinear = .false.
    real(wp) :: tensile_strength = 0.0_wp, compressive_strength = 0.0_wp
    real(wp) :: shear_strength = 0.0_wp
    integer :: history_depth = 8
    !> Fracture (docs/model.md, "Fracture"): springs that soften and fail. Each criterion
    !> (tension and crushing of edge springs, shear of shear springs) is on when its strength
    !> (the three above) or its limit strain is given, with its fracture energy (J/m^2);
    !> 0: not given.
    logical :: fracture = .false.
    !> Softening shape of every criterion: 'linear' or 'bilinear' (docs/model.md).
    character(len=8) :: softening = 'linear'
    real(wp) :: tensile_failure_strain = 0.0_wp, compressive_failure_strain = 0.0_wp
    real(wp) :: shear_failure_strain = 0.0_wp
    real(wp) :: fracture_energy = 0.0_wp, crushing_energy = 0.0_wp
    real(wp) :: shear_fracture_energy = 0.0_wp
  end type material_config_t

  !> A set of nodes of the body (docs/input.md, Node sets): where = 'left', 'right', 'bottom',
  !> 'top' (nodes on that side of the grid), 'all', 'box' (box = x0, x1, y0, y1), 'point'
  !> (the node nearest to point), 'segment' (nodes on the segment = x0, y0, x1, y1),
  !> 'circle' (nodes in the disc center, radius), 'boundary' (nodes on the body's
  !> boundary), 'shape' (boundary nodes on the outline of the named shape; shape_id
  !> resolved), 'face' (boundary nodes of the edges whose outward normal is normal).
  type :: node_set_spec_t
    character(len=8) :: where = ''
    real(wp) :: box(4) = 0.0_wp
    real(wp) :: point(2) = 0.0_wp
    real(wp) :: segment(4) = 0.0_wp
    real(wp) :: center(2) = 0.0_wp, radius = 0.0_wp
    character(len=name_len) :: shape = ''
    integer :: shape_id = 0
    real(wp) :: normal(2) = 0.0_wp
    !> 'point': the node of the body nearest to point, found at set-up (-1 before).
    integer(i8) :: node = -1
  end type node_set_spec_t

  !> Time function of a load or prescribed velocity: constant, step or linear ramp.
  type :: time_function_spec_t
    character(len=8) :: kind = 'constant'
    real(wp) :: t_start = 0.0_wp
    real(wp) :: t_ramp = 0.0_wp
  end type time_function_spec_t

  !> One boundary condition (&bc).
  type :: bc_config_t
    character(len=name_len) :: name = ''
    type(node_set_spec_t) :: set
    character(len=8) :: kind = 'fix'
    logical :: dof(2) = .false.
    real(wp) :: velocity(2) = 0.0_wp
    type(time_function_spec_t) :: tf
    !> Time (s) from which the condition no longer acts (the dofs are released); huge: never.
    real(wp) :: t_release = huge(1.0_wp)
  end type bc_config_t

  !> One load (&load).
  type :: load_config_t
    character(len=name_len) :: name = ''
    character(len=8) :: kind = 'nodal'
    type(node_set_spec_t) :: set
    real(wp) :: value(2) = 0.0_wp
    type(time_function_spec_t) :: tf
  end type load_config_t

  !> Rayleigh damping, resolved to alpha (mass) and beta (stiffness) coefficients.
  type :: damping_config_t
    character(len=12) :: kind = 'none'
    real(wp) :: alpha = 0.0_wp, beta = 0.0_wp
    real(wp) :: ratio = 0.0_wp, frequency = 0.0_wp
    !> kind = 'capped': stiffness damping acts on the velocity low-pass filtered at this
    !> frequency (Hz); beta is then found by the model for ratio at frequency.
    real(wp) :: cap_frequency = 0.0_wp
  end type damping_config_t

  !> Initial velocity field (&initial; dynamic runs): a uniform velocity plus a rigid spin
  !> at angular_velocity (rad/s, counter-clockwise) about center.
  type :: initial_config_t
    real(wp) :: velocity(2) = 0.0_wp
    real(wp) :: angular_velocity = 0.0_wp
    real(wp) :: center(2) = 0.0_wp
    logical :: given = .false.
  end type initial_config_t

  !> Quasi-static analysis by dynamic relaxation (&static; only with analysis = 'static').
  type :: static_config_t
    !> Whether the input has a &static group.
    logical :: given = .false.
    integer :: load_steps = 10
    real(wp) :: tolerance = 1.0e-6_wp
    integer :: max_iterations = 200000
    !> 'kinetic' (kinetic damping) or 'viscous' (adaptive viscous damping).
    character(len=8) :: method = 'kinetic'
    !> 'lumped' (the model's masses, step from the cell bound) or 'gershgorin' (per-dof
    !> fictitious masses from stiffness row sums, unit step).
    character(len=12) :: mass = 'lumped'
  end type static_config_t

  !> A named point whose nearest node is recorded in the history.
  type :: probe_config_t
    character(len=name_len) :: name = ''
    real(wp) :: x = 0.0_wp, y = 0.0_wp
    !> Also record the strain and stress of the 12 springs of the cell that holds (x, y).
    logical :: springs = .false.
  end type probe_config_t

  !> The whole validated configuration of a run.
  type :: config_t
    character(len=path_len) :: input_file = ''
    character(len=:), allocatable :: input_text
    type(run_config_t) :: run
    type(geometry_config_t) :: geometry
    !> Materials (at least one); the first is the default background.
    type(material_config_t), allocatable :: materials(:)
    type(shape_config_t), allocatable :: shapes(:)
    type(damping_config_t) :: damping
    type(static_config_t) :: static
    type(initial_config_t) :: initial
    type(bc_config_t), allocatable :: bcs(:)
    type(load_config_t), allocatable :: loads(:)
    type(probe_config_t), allocatable :: probes(:)
  end type config_t
end module iem_config
