!> The elastic lattice model on one rank: spring constants, masses, loads, boundary
!> conditions, damping, and the rate (accelerations) of the first-order system (u, v).
module iem_model
  use mpi_f08, only: MPI_Request
  use iem_kinds, only: wp, ip, i8
  use iem_config, only: config_t
  use iem_grid, only: grid_t
  use iem_body, only: body_t
  use iem_local_lattice, only: local_lattice_t
  use iem_cell_table, only: max_chunk, cell_table_t
  use iem_node_sets, only: select_nodes
  use iem_spring_constants, only: cell_constants_t, cell_constants
  use iem_cell_kernel, only: cell_forces, kernel_rows, kernel_slots_t
  use iem_cell_chunk, only: edge_row_t
  use iem_cell_split, only: cell_split_t
  use iem_cell_bands, only: cell_bands_t
  use iem_halo, only: halo_t
  use iem_node_pass, only: rk4_stage_t, accelerations, rk4_first_pass, rk4_mid_pass, &
                           rk4_last_pass, mass_damping_powers
  use iem_nonlinear_springs, only: nonlinear_springs_t, reference_strains
  use iem_time_function, only: time_function_t, tf_value, tf_rate
  use iem_strings, only: itoa
  use iem_constants, only: pi
  use iem_stable_dt, only: capped_beta
  use iem_alloc_guard, only: alloc_guard_t
  use iem_exact_sum, only: exact_sum_t
  use iem_sort, only: order_by_node
  use iem_stage_wave, only: stage_wave_t, wave_stages
  use iem_fracture, only: fracture_t
  use iem_fracture_law, only: fracture_law_t
  use iem_input_fracture, only: material_fracture_law
  implicit none
  private
  public :: model_t, work_collect_steps

  !> The time loop moves the nodes' mass-damping work (wd_node) into the exact sum at the
  !> steps that are multiples of this (collect_work), the same steps on any number of ranks.
  integer, parameter :: work_collect_steps = 16

  !> Everything the force evaluation of one rank needs, with preallocated work arrays.
  type :: model_t
    type(grid_t) :: grid
    !> Cell constants and density of each material; k is that of material 1 (the only one
    !> of a single-material body; its geometry lx, ly, il0 is that of every cell).
    type(cell_constants_t) :: k
    type(cell_constants_t), allocatable :: ks(:)
    real(wp), allocatable :: densities(:)
    !> Whether the cells have several materials (the kernel then reads each cell's).
    logical :: mixed = .false.
    real(wp) :: density = 0.0_wp, alpha = 0.0_wp, beta = 0.0_wp
    !> Capped stiffness damping: the stiffness damping acts on w, the velocity low-pass
    !> filtered at omega_cap (rad/s), carried as state rows 5:6; 0 when not used.
    real(wp) :: omega_cap = 0.0_wp
    !> Velocity Verlet's step while it evaluates the forces at its end (0 otherwise): the powers
    !> of the loads, of the reactions and of capped damping are then those of the forces' mean
    !> over the step, as its kicks apply them (the start's and the end's, half a step each
    !> around the half-step velocity; docs/model.md).
    real(wp) :: mean_dt = 0.0_wp
    !> With mean_dt, the loads' mean over the step at each loaded slot, where it differs from
    !> fext (fmean_on; allocated the first time it does).
    real(wp), allocatable :: fmean(:, :)
    logical :: fmean_on = .false.
    !> State values per node: 4 (u, v), or 6 (u, v, w) with capped damping.
    integer :: n_state = 4
    !> Nonlinear (Masing) springs: their laws and history; not allocated for elastic runs.
    logical :: nonlinear = .false.
    type(nonlinear_springs_t) :: nl
    !> Fracture (springs that soften and fail): its state; not allocated when no material
    !> can fracture and no shape pre-cuts cells.
    logical :: fracture = .false.
    type(fracture_t) :: fr
    !> Lumped mass of owned nodes.
    real(wp), allocatable :: mass(:)
    !> Prescribed degrees of freedom: owned node, component, bc index.
    integer, allocatable :: bc_node(:), bc_comp(:), bc_id(:)
    real(wp), allocatable :: bc_velocity(:, :)
    type(time_function_t), allocatable :: bc_tf(:)
    !> Time from which each &bc no longer acts (huge: never released).
    real(wp), allocatable :: bc_release(:)
    !> Load entries: owned node, force vector at full load, load index.
    integer, allocatable :: load_node(:), load_id(:)
    real(wp), allocatable :: load_force(:, :)
    type(time_function_t), allocatable :: load_tf(:)
    real(wp), allocatable :: load_scale(:)
    !> Work array: cell forces summed per local node; all zero between evaluations (the
    !> pass that reads a node's force clears it, so no separate pass clears the array).
    !> Without columns when sum_in_acc.
    real(wp), allocatable :: f(:, :)
    !> Velocity Verlet with 4 values a node: the forces are summed into the rates array acc
    !> (n_local columns, all zero on entry: its first kick clears what it reads) and the pass
    !> turns them into the accelerations in place; no separate force array.
    logical :: sum_in_acc = .false.
    !> The interior and boundary chunks, for evaluations that overlap the halo exchange (the
    !> evaluations without it walk the lattice's own chunks, lat%cells).
    type(cell_split_t) :: split
    !> The bands of the lattice's chunks (with halo nodes, of the split's interior chunks) for
    !> an RK4 stage's evaluation: the stage's pass over the nodes follows the cells band by
    !> band (docs/architecture.md, "The node pass band by band").
    type(cell_bands_t) :: bands
    !> The prescribed dofs in the order of their nodes (stable): bc_by_node(j) is an entry of
    !> bc_node.
    integer, allocatable :: bc_by_node(:)
    !> Whether each prescribed dof's reaction power entered p_ext at the last evaluation.
    logical, allocatable :: pr_on(:)
    !> The force kernel's work space (its node rows, about 200 kB).
    type(edge_row_t), allocatable :: rows(:)
    !> Which of its rows the kernel's slots hold, between the bands of one evaluation.
    type(kernel_slots_t) :: slots
    !> Cell forces of the prescribed dofs, for the reactions.
    real(wp), allocatable :: f_bc(:)
    !> External forces, stored only for the owned nodes that carry a load: ext_node(s) is
    !> the node of slot s (ascending), fext(:, s) its summed load; load_slot(n) is the slot of
    !> load entry n, bc_slot(q) that of prescribed dof q (0: the node carries no load).
    integer, allocatable :: ext_node(:), load_slot(:), bc_slot(:)
    real(wp), allocatable :: fext(:, :)
    !> Scratch for the kernel's plain energy sum, which the model does not ask for (0): the
    !> energies that a sample reports are the exact sum en_sum.
    real(wp) :: energy = 0.0_wp
    !> Whether a committed evaluation sums the cells' energies into en_sum (a recorded one
    !> always does): the time loop clears it for the states that no history sample reads.
    logical :: energies_due = .true.
    !> The strain energy of the counted cells at the last committed or recorded evaluation,
    !> summed exactly (so independent of the partition) as the kernel forms each cell's.
    type(exact_sum_t) :: en_sum
    !> The terms of the last rate evaluation, kept so that global sums are exact and so
    !> independent of the partition: each local cell's damping power (only with stiffness
    !> damping, else empty), each owned node's mass-damping power (only with mass damping,
    !> else empty), the power of each loaded node's loads and of each prescribed dof's
    !> reaction.
    real(wp), allocatable :: pw_cell(:), pw_node(:), pe_slot(:), pr_bc(:)
    !> f_int - f_ext of each prescribed dof at the last committed evaluation: the reactions
    !> less the inertia of the prescribed motion. Moved and checkpointed with the node, as a
    !> node field 'reaction' of width 2 (an integrator's resume evaluates without commit).
    real(wp), allocatable :: r_bc(:)
    !> External work and damping dissipation of this rank since the start: exact sums of the
    !> weighted terms of every evaluation the integrator counts (add_work). The mass
    !> damping's terms reach w_damp_acc through wd_node.
    type(exact_sum_t) :: w_ext_acc, w_damp_acc
    !> Each owned node's mass-damping work (its weighted powers, summed in the order of the
    !> evaluations) since the last collect_work, which the time loop calls at fixed steps:
    !> one exact deposit a node every few steps instead of one an evaluation (only with
    !> mass damping, else empty). A node field ('damping_work'): moved and checkpointed.
    real(wp), allocatable :: wd_node(:)
    !> Likewise each local cell's stiffness-damping work (only with stiffness damping, else
    !> empty; every copy of a cell folds the same terms, the counted one is collected): the
    !> cell field 'cell_damping_work'.
    real(wp), allocatable :: wd_cell(:)
    !> RK4's stages as one wavefront over bands of its own where it applies (stages_fit;
    !> rate_stages; with halo nodes each stage's strip first); waves = .false. evaluates
    !> them one after the other.
    type(stage_wave_t) :: wave
    logical :: waves = .true.
  contains
    procedure :: init => model_init
    procedure :: rate => model_rate
    procedure :: prescribe => model_prescribe
    procedure :: add_work => model_add_work
    procedure :: collect_work => model_collect_work
    procedure :: damping_work => model_damping_work
    procedure :: energy_sums => model_energy_sums
    procedure :: kick_term => model_kick_term
    procedure :: slot_power
    procedure :: reaction_sums => model_reaction_sums
    procedure :: rate_columns => model_rate_columns
    procedure :: rate_stages => model_rate_stages
    procedure :: cells => model_cells
    procedure :: reaction_terms => model_reaction_terms
    procedure :: stages_fit => model_stages_fit
    procedure :: set_bands => model_set_bands
    procedure :: verlet_pair => model_verlet_pair
    procedure :: pair_fits => model_pair_fits
  end type model_t

  interface
    !> Accelerations acc(2, n_owned) of the owned nodes for the state y(4, n_local) (halo
    !> columns up to date, or brought up to date here with halo) at time t; also the local
    !> power of external forces (loads and support reactions) and of damping, for the energy
    !> balance.
    !> With nonlinear springs, commit = .true. accepts y: the springs' history moves to it
    !> (default: trial only). With halo, the exchange of y's halo overlaps the interior cells'
    !> forces (iem_cell_split; bitwise the same results); the caller times the call as force
    !> evaluation, and the halo's share goes to the halo exchange's timer.
    !> With stage (an RK4 stage of a model with 4 state values a node, or 6 with capped
    !> damping's filtered velocities), the stage's update is fused into the pass over the
    !> nodes instead, which without stiffness damping follows the cells band by band
    !> (model%bands) (iem_node_pass, iem_node_pass_filtered; acc then holds only the
    !> imposed accelerations of the prescribed dofs): stage 1 at y writes ynew and the next
    !> stage state ynext; stages 2 and 3 at the stage state y add to ynew and turn y into the
    !> next stage state from y0, the state at the start of the step; stage 4 adds to ynew and
    !> sums it into stage%total. With kick (velocity Verlet), the guarded v += kick a follows in
    !> the pass (where the new velocities are not finite acc keeps the half-step ones), and
    !> first_bad is the first owned node where they are not (0: none; iem_node_pass's
    !> kick_node); the prescribed dofs' rates are then left as the pass left them. With kick
    !> and drift (a state of 4 values a node, its forces summed into acc), the next step's
    !> first kick and drift follow in the pass where the kick was finite, and acc is cleared
    !> there for the next step's forces (iem_node_pass's accelerations_in_place; prescribed
    !> dofs included: their values are the caller's to set).
    module subroutine model_rate(this, lat, y, t, acc, p_ext, p_damp, commit, record, stage, &
                                 y0, ynew, ynext, kick, halo, vote, vote_all, first_bad, drift, &
                                 cells_done, fold)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      real(wp), intent(inout), contiguous :: y(:, :)
      real(wp), intent(in) :: t
      real(wp), intent(inout), contiguous :: acc(:, :)
      real(wp), intent(out) :: p_ext, p_damp
      logical, intent(in), optional :: commit
      !> Sum the cells' energies (en_sum) also without commit (default: only with commit
      !> and energies_due, the accepted states whose energies a history sample reports).
      logical, intent(in), optional :: record
      type(rk4_stage_t), intent(inout), optional :: stage
      real(wp), intent(in), optional, contiguous :: y0(:, :)
      real(wp), intent(inout), optional, contiguous :: ynew(:, :), ynext(:, :)
      !> Velocity Verlet's second kick, fused into the pass: v += kick a (prescribed velocities
      !> are the caller's to set afterwards).
      real(wp), intent(in), optional :: kick
      !> The halo exchange of y, done here.
      type(halo_t), intent(inout), optional :: halo
      !> A pending agreement (an MPI_Iallreduce into vote_all) that the pass over the nodes
      !> waits for; when vote_all comes back .false. the pass is skipped (f is cleared).
      type(MPI_Request), intent(inout), optional :: vote
      logical, intent(inout), optional, asynchronous :: vote_all
      integer, intent(out), optional :: first_bad
      !> With kick: the next step's dt, its first kick and drift fused into the pass.
      real(wp), intent(in), optional :: drift
      !> The cells' forces at y are in acc already (the last verlet_pair's next step).
      logical, intent(in), optional :: cells_done
      !> The evaluation's weight in the step's work: the nodes' mass damping work is folded
      !> into wd_node as the powers are formed (add_work is then told so).
      real(wp), intent(in), optional :: fold
    end subroutine model_rate

    !> The cell forces of the chunks of table (range: only those; at: the split's routed
    !> chunks) at the state y, added to fs, with the kernel's node rows and slots: accept
    !> commits the springs' history and the damage at time, terms takes the counted cells'
    !> energies; pd the kernel's damping power; damaged: whether fracture has damaged a cell;
    !> split: the split whose routes and side slots at refers to (default: the model's).
    module subroutine model_cells(this, lat, table, y, fs, accept, time, rows, slots, pd, at, &
                                  terms, range, damaged, split)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      type(cell_table_t), intent(in) :: table
      real(wp), intent(in), contiguous :: y(:, :)
      real(wp), intent(inout), contiguous :: fs(:, :)
      logical, intent(in) :: accept
      real(wp), intent(in) :: time
      type(edge_row_t), intent(inout) :: rows(:)
      type(kernel_slots_t), intent(inout) :: slots
      real(wp), intent(out) :: pd
      integer, intent(in), optional, contiguous :: at(:)
      type(exact_sum_t), intent(inout), optional :: terms
      integer, intent(in), optional :: range(2)
      logical, intent(out), optional :: damaged
      type(cell_split_t), intent(inout), optional :: split
    end subroutine model_cells

    !> Prescribed dof q at an evaluated state y at time t, from its node's cell forces in fs
    !> (before the loads fext are taken off): its cell force f_bc, with keep its reaction r_bc,
    !> and its reaction's power pr (on: whether it enters p_ext: not released, moving); with
    !> mean_dt, that of the reaction's mean over the step (r_bc before it, the last accepted
    !> state's, is the start's).
    module subroutine model_reaction_terms(this, q, fs, y, t, fext, keep, pr, on)
      class(model_t), intent(inout) :: this
      integer, intent(in) :: q
      real(wp), intent(in), contiguous :: fs(:, :), y(:, :), fext(:, :)
      real(wp), intent(in) :: t
      logical, intent(in) :: keep
      real(wp), intent(out) :: pr
      logical, intent(out) :: on
    end subroutine model_reaction_terms

    !> RK4's stages first..4 (first: 1 or 2) of a step with 4 state values a node, as
    !> model_rate with stage evaluates each in turn (stage 1 with commit), but as one
    !> wavefront over the bands (where stages_fit): stage 1 at y0, the others at the stage
    !> states in ys (with first = 2, stage 2's, its prescribed dofs set), at the times ts, the
    !> passes' weights wdt and offsets h into ynew and ys from y0, each next stage state's
    !> prescribed velocities set at its time as its nodes are made; each stage's powers p_ext
    !> and p_damp, their terms added to the work and dissipation times wdt (add_work), stage
    !> 4's sum of the new values in total, and acc's imposed accelerations as the calls
    !> leave them. No energies are summed (energies_due is .false.). On a rank with halo
    !> nodes (halo needed) each stage first evaluates its strip, whose nodes include those
    !> the neighbours receive, exchanges them, and then goes on with its bands (y0's halo
    !> columns exchanged here with first = 1).
    module subroutine model_rate_stages(this, lat, first, ys, y0, ynew, acc, ts, wdt, h, &
                                        p_ext, p_damp, total, halo)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      integer, intent(in) :: first
      real(wp), intent(inout), contiguous :: ys(:, :), ynew(:, :), acc(:, :)
      real(wp), intent(inout), contiguous :: y0(:, :)
      real(wp), intent(in) :: ts(wave_stages), wdt(wave_stages), h(wave_stages)
      real(wp), intent(out) :: p_ext(wave_stages), p_damp(wave_stages), total
      type(halo_t), intent(inout), optional :: halo
    end subroutine model_rate_stages

    !> The bands of the lattice's chunks (with halo nodes, of the split's interior chunks),
    !> each completing at least band_nodes nodes (default: iem_cell_bands'
    !> band_nodes_default), and RK4's wavefront: its bands of at least wave_nodes nodes
    !> (default: band_nodes where given, else iem_stage_wave's wave_band_nodes) and their
    !> schedule (with halo nodes, each stage's strip and bands, iem_stage_wave's
    !> init_strips).
    module subroutine model_set_bands(this, lat, band_nodes, wave_nodes)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      integer, intent(in), optional :: band_nodes, wave_nodes
    end subroutine model_set_bands

    !> Velocity Verlet's step evaluated at t1 (model_rate with commit, kick h and drift dt)
    !> and the next step's cell forces (at t_next + dt) summed into acc, as one wavefront over
    !> the bands; u_bc: the prescribed dofs' displacements before the pass (mended at t_next
    !> as iem_verlet's mend_prescribed does). Bit for bit model_rate's results, and the next
    !> step's forces those of its evaluation (cells_done) where paired (not where fracture
    !> damages a cell there: its commit would change the cell); first_bad as model_rate's
    !> (then no dof is mended and acc is as model_rate leaves it); the nodes' mass damping
    !> work folded with the weight dt (model_rate's fold). iem_model_pair.f90.
    module subroutine model_verlet_pair(this, lat, y, t1, t_next, h, dt, acc, u_bc, ready, &
                                        p_ext, p_damp, first_bad, paired)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      real(wp), intent(inout), contiguous :: y(:, :), acc(:, :)
      real(wp), intent(in) :: t1, t_next, h, dt, u_bc(:)
      !> The step's cell forces are in acc already (the last pair's next step).
      logical, intent(in) :: ready
      real(wp), intent(out) :: p_ext, p_damp
      integer, intent(out) :: first_bad
      logical, intent(out) :: paired
    end subroutine model_verlet_pair

    !> Whether velocity Verlet's steps can pair (verlet_pair) on lat with n_state values a
    !> node: no halo nodes, bands, elastic springs, no stiffness or capped damping.
    module logical function model_pair_fits(this, lat, n_state) result(fit)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      integer, intent(in) :: n_state
    end function model_pair_fits

    !> Whether RK4's stages can go as one wavefront (rate_stages) on the lattice lat with
    !> n_state values a node.
    module logical function model_stages_fit(this, lat, n_state) result(fit)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      integer, intent(in) :: n_state
    end function model_stages_fit

    !> Add the powers of the last rate evaluation, each times wdt (its weight in the time
    !> integral of the step), to the external work exactly and to the damping dissipation
    !> (each node's wd_node, each cell's wd_cell: collect_work moves them into the exact sum);
    !> lat: the lattice of the evaluation.
    module subroutine model_add_work(this, lat, wdt, folded)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
      real(wp), intent(in) :: wdt
      !> The evaluation folded its mass damping work already (its fold argument was wdt).
      logical, intent(in), optional :: folded
    end subroutine model_add_work

    !> Move each owned node's mass-damping work (wd_node) and each counted cell's
    !> stiffness-damping work (wd_cell) into w_damp_acc exactly and clear them.
    module subroutine model_collect_work(this, lat)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
    end subroutine model_collect_work

    !> This rank's damping dissipation so far, exactly: w_damp_acc, the nodes' wd_node and the
    !> counted cells' wd_cell.
    module function model_damping_work(this, lat) result(acc)
      class(model_t), intent(in) :: this
      type(local_lattice_t), intent(in) :: lat
      type(exact_sum_t) :: acc
    end function model_damping_work

    !> This rank's exact sums of the kinetic energy of y (owned nodes), the strain energy of
    !> the last rate evaluation (counted cells), the external work, the damping dissipation
    !> and the fracture dissipation (counted cells), in sums(1:5), and the kicks' term
    !> sums(6) (below), for an exact global sum (exact_sum_allreduce).
    module subroutine model_energy_sums(this, lat, y, sums, acc, h)
      class(model_t), intent(in) :: this
      type(local_lattice_t), intent(in) :: lat
      real(wp), intent(in) :: y(:, :)
      type(exact_sum_t), intent(out) :: sums(6)
      !> The accelerations at y and the half step h of the kicks around it (velocity Verlet):
      !> sums(6) is then kick_term (else 0), which the kinetic energy sums(1) less is what
      !> the kicks' work balances (docs/model.md, "Time integration").
      real(wp), intent(in), optional :: acc(:, :), h
    end subroutine model_energy_sums

    !> Velocity Verlet's kicks' term at a state whose accelerations are a (owned nodes), the
    !> kicks around it of half step h (0: none, the sum is 0): (1/2) m h^2 |a|^2 over the
    !> owned nodes, and h/2 times the mass and plain stiffness damping power of the last
    !> evaluation (owned nodes, counted cells; capped damping's work takes the step's mean
    !> force and needs none), exactly (docs/model.md, "Time integration").
    module function model_kick_term(this, lat, a, h) result(acc)
      class(model_t), intent(in) :: this
      type(local_lattice_t), intent(in) :: lat
      real(wp), intent(in) :: a(:, :), h
      type(exact_sum_t) :: acc
    end function model_kick_term

    !> Add the reactions of this rank's prescribed dofs at the last committed evaluation (the
    !> accepted state y at time t) to sums(2*(s - 1) + comp), s = series(b) of the dof's &bc
    !> b, exactly: the force R = m (a + alpha v) + f_int - f_ext the support exerts on the
    !> body (inertia = .false., static runs: f_int - f_ext); a released condition exerts
    !> none.
    module subroutine model_reaction_sums(this, y, t, series, inertia, sums)
      class(model_t), intent(in) :: this
      real(wp), intent(in) :: y(:, :)
      real(wp), intent(in) :: t
      integer, intent(in) :: series(:)
      logical, intent(in) :: inertia
      type(exact_sum_t), intent(inout) :: sums(:)
    end subroutine model_reaction_sums
    !> The loads fext at time t (their scales in load_scale): rebuilt only when a time
    !> function has changed; with mean_dt, also their mean over the step to t (fmean), where
    !> it differs.
    module subroutine model_set_loads(this, t)
      class(model_t), intent(inout) :: this
      real(wp), intent(in) :: t
    end subroutine model_set_loads

    !> The terms of the owned nodes lo..hi at the state y at time t, whose cell forces are
    !> complete in fs, before a pass over them: the reactions (keep: kept) and reaction powers
    !> of their prescribed dofs, their loads' powers and loads (taken off fs), their mass
    !> damping powers (pw_node; the sums are the caller's). jb and js: where the search in
    !> bc_by_node and the load slots starts, left after the run (j0: its first dof).
    module subroutine model_run_terms(this, lo, hi, fs, y, t, keep, jb, js, j0, fold)
      class(model_t), intent(inout) :: this
      integer, intent(in) :: lo, hi
      real(wp), intent(inout), contiguous :: fs(:, :)
      real(wp), intent(in), contiguous :: y(:, :)
      real(wp), intent(in) :: t
      logical, intent(in) :: keep
      integer, intent(inout) :: jb, js
      integer, intent(out) :: j0
      !> The evaluation's weight in the step's work: its mass damping work folded (wd_node).
      real(wp), intent(in), optional :: fold
    end subroutine model_run_terms

    !> The mass damping powers of the nodes lo..hi at the last evaluation (pw_node), times
    !> wdt, added to their wd_node (each node's terms in the order of the evaluations).
    module subroutine model_fold_work(this, lo, hi, wdt)
      class(model_t), intent(inout) :: this
      integer, intent(in) :: lo, hi
      real(wp), intent(in) :: wdt
    end subroutine model_fold_work

    !> The damping's terms sized for lat (pw_cell and wd_cell with stiffness damping, pw_node
    !> and wd_node with mass damping), zeros where new: the damping may be set after init.
    module subroutine model_damping_arrays(this, lat)
      class(model_t), intent(inout) :: this
      type(local_lattice_t), intent(in) :: lat
    end subroutine model_damping_arrays

    !> The power of the last evaluation's loads (pe_slot) and of the reactions that enter it
    !> (pr_bc where pr_on), each summed in its order.
    module pure real(wp) function model_external_power(this) result(p)
      class(model_t), intent(in) :: this
    end function model_external_power

    !> Build the model of this rank from the configuration, its body and its local lattice;
    !> n_selected counts, per &bc then per &load, the owned nodes each selects (the caller
    !> sums them). A failed allocation is handed to guard (the model is then incomplete);
    !> without guard it stops the program (iem_model_init.f90).
    module subroutine model_init(this, cfg, body, lat, n_selected, guard)
      class(model_t), intent(inout) :: this
      type(config_t), intent(in) :: cfg
      type(body_t), intent(in) :: body
      type(local_lattice_t), intent(in) :: lat
      integer(i8), intent(out) :: n_selected(:)
      type(alloc_guard_t), intent(inout), optional :: guard
    end subroutine model_init

  end interface

contains


  !> Overwrite the velocities of prescribed dofs in y(4, :) with their values at time t
  !> (released conditions, t >= t_release, no longer act).
  subroutine model_prescribe(this, y, t)
    class(model_t), intent(in) :: this
    real(wp), intent(inout) :: y(:, :)
    real(wp), intent(in) :: t
    integer :: q, b
    do q = 1, size(this%bc_node)
      b = this%bc_id(q)
      if (t >= this%bc_release(b)) cycle
      y(2 + this%bc_comp(q), this%bc_node(q)) = this%bc_velocity(this%bc_comp(q), b)* &
                                                tf_value(this%bc_tf(b), t)
    end do
  end subroutine model_prescribe

  !> The power at the state y of slot s's loads: of their mean over velocity Verlet's step
  !> where it differs from fext (fmean_on), else of fext.
  pure real(wp) function slot_power(this, s, y) result(p)
    class(model_t), intent(in) :: this
    integer, intent(in) :: s
    real(wp), intent(in) :: y(:, :)
    integer :: l
    l = this%ext_node(s)
    if (this%fmean_on) then
      p = this%fmean(1, s)*y(3, l) + this%fmean(2, s)*y(4, l)
    else
      p = this%fext(1, s)*y(3, l) + this%fext(2, s)*y(4, l)
    end if
  end function slot_power

  !> Columns the state's rates array acc needs for this model: none for RK4 with 4 values a
  !> node (rk4_work; its fused passes never read it), every local node's when the forces are
  !> summed into it (sum_in_acc, velocity Verlet), else the owned nodes'.
  pure integer function model_rate_columns(this, lat, rk4_work) result(n)
    class(model_t), intent(in) :: this
    type(local_lattice_t), intent(in) :: lat
    logical, intent(in) :: rk4_work
    n = lat%n_owned
    if (rk4_work .and. this%n_state == 4) n = 0
    if (this%sum_in_acc) n = lat%n_local
  end function model_rate_columns
end module iem_model
