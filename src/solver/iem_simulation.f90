!> A whole run: set up the lattice, model and output from a validated configuration, then
!> march in time with an integrator (analysis = 'dynamic') or relax load step by load step
!> (analysis = 'static'), recording history, frames and progress. This module holds the run's
!> type and its entry points, which only sequence the parts that live in the submodules:
!> set-up (_setup), the time loop (_dynamic) and its schedule of the steps that read the state
!> (_schedule), the history recorder and frames (_output), checkpoints and continued runs
!> (iem_restart), the run's fields for checkpoints and repartitioning (_fields), the guards
!> (_guards), the ranks' agreement on a non-finite step (_agreement), the static load steps
!> (_static) and the reports (_report); the integrators are behind iem_integrator's interface
!> (docs/architecture.md).
module iem_simulation
  use mpi_f08, only: MPI_Comm, MPI_Allreduce, MPI_MAX, MPI_IN_PLACE, MPI_Wtime, MPI_LOGICAL, &
    MPI_LAND, MPI_INTEGER
  use iem_kinds, only: wp, i8
  use iem_config, only: config_t
  use iem_grid, only: grid_t
  use iem_body, only: body_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t, work_collect_steps
  use iem_state, only: state_t
  use iem_integrator, only: integrator_t
  use iem_relaxation, only: relaxation_t
  use iem_checkpoint, only: checkpoint_header_t
  use iem_fields, only: field_registry_t
  use iem_signals, only: install_signal_handlers, signal_caught
  use iem_h5_output, only: h5_output_t
  use iem_logger, only: log_info
  use iem_heap, only: heap_release
  use iem_underflow, only: flush_subnormals, restore_underflow
  use iem_timers, only: timer_start, timer_stop, t_output
  use iem_strings, only: itoa, rtoa
  use iem_alloc_guard, only: alloc_guard_t
  use iem_exact_sum, only: exact_sum_t
  use iem_fracture_events, only: fracture_events_t
  use iem_fragments, only: fragments_t, n_largest
  implicit none
  private
  public :: simulation_t

  !> One run: configuration, decomposition, model, state, output and the history buffer.
  type :: simulation_t
    type(MPI_Comm) :: comm
    integer :: rank = 0, n_ranks = 1
    type(config_t) :: cfg
    type(grid_t) :: grid
    !> The body cut from the grid, with the numbering of its nodes and cells.
    type(body_t) :: body
    type(local_lattice_t) :: lat
    type(halo_t) :: halo
    type(model_t) :: model
    type(state_t) :: st
    !> Dynamic relaxation of a static run.
    type(relaxation_t) :: relax
    logical :: static = .false.
    !> Dynamic runs: &run integrator is velocity Verlet (for the set-up's memory estimate and
    !> the checkpoint's header; the time loop asks integ instead).
    logical :: verlet = .false.
    !> Dynamic runs: the time integrator (iem_integrator_factory).
    class(integrator_t), allocatable :: integ
    type(h5_output_t) :: out
    real(wp) :: dt = 0.0_wp, dt_limit = 0.0_wp, omega_max = 0.0_wp
    integer(i8) :: n_steps = 0
    !> Probes: nearest global node, local index when owned here (0 otherwise).
    integer(i8), allocatable :: probe_gid(:)
    integer, allocatable :: probe_local(:)
    !> History buffer: samples not yet written.
    integer :: n_buf = 0
    real(wp), allocatable :: h_time(:), h_energy(:, :), h_pu(:, :, :), h_pv(:, :, :)
    integer(i8), allocatable :: h_step(:)
    !> Spring probes (probes with springs = .true.): probe index, global cell, local cell
    !> when counted here (0 otherwise); buffered strains and stresses (12, n, samples).
    integer, allocatable :: sp_probe(:), sp_local(:)
    integer(i8), allocatable :: sp_cell(:)
    real(wp), allocatable :: h_sp_e(:, :, :), h_sp_s(:, :, :)
    !> Spring moduli (Eq, Hq, Gq) of each spring probe's cell: a spring's stress is its
    !> modulus times its normalised stress (its strain, when elastic).
    real(wp), allocatable :: moduli(:, :)
    !> Nonlinear runs: the degree of nonlinearity of each counted cell, for frames.
    real(wp), allocatable :: cell_degree(:)
    !> Static runs: load factor, iterations and relative residual of each buffered sample.
    real(wp), allocatable :: h_load(:), h_res(:)
    integer(i8), allocatable :: h_iter(:)
    real(wp), allocatable :: sample(:)
    !> Reactions: the series of each &bc (&bc of one name share one), each series' name and
    !> &bc (1-based, as text), and the buffered samples (2, series, samples).
    integer, allocatable :: bc_series(:)
    character(len=64), allocatable :: series_names(:)
    character(len=256), allocatable :: series_bcs(:)
    real(wp), allocatable :: h_react(:, :, :)
    !> The exact sums of a sample: the five energies, velocity Verlet's kicks' term (0 with
    !> RK4), then x and y of each reaction series.
    type(exact_sum_t), allocatable :: xsums(:)
    !> Fracture: the event log; the fragment count's work arrays, the last count and its
    !> largest fragments (frag_valid: counted since this process started); buffered samples.
    type(fracture_events_t) :: events
    type(fragments_t) :: frag
    logical :: frag_valid = .false.
    integer(i8) :: n_frag = 0, frag_sizes(n_largest) = 0
    integer(i8), allocatable :: h_frag(:), h_largest(:, :)
    real(wp) :: e0 = 0.0_wp, e_scale = 0.0_wp, last_balance = 0.0_wp
    real(wp) :: w_ext = 0.0_wp, w_damp = 0.0_wp
    !> Velocity Verlet's kicks' term (the model's kick_term, global, rounded) at the step
    !> kick_step of a checkpoint or a repartitioning, for a sample at that step (-1: none):
    !> the evaluation since took the state's velocities for the damping, not the half step's.
    real(wp) :: kick = 0.0_wp
    integer(i8) :: kick_step = -1
    logical :: output_open = .false.
    !> Guards: whether the energy warning has been given.
    logical :: warned = .false.
    !> Restart: the checkpoint's header (step 0: a fresh run).
    type(checkpoint_header_t) :: restart
    !> The last history sample written (time and the five energies) and the time of the last
    !> frame: a checkpoint records them to recognise its output on a restart.
    real(wp) :: last_sample(7) = 0.0_wp, last_frame_time = 0.0_wp
    !> Dynamic runs on more than one rank (the integrator's local): this rank's first rejected
    !> step since the last agreement (huge: none); the origin, the state a diverging run steps
    !> again from: the checkpoint this run wrote last, or the one it continues from, or, empty,
    !> the initial state (a run from step 0 before its first checkpoint).
    integer(i8) :: k_bad = huge(1_i8)
    character(len=:), allocatable :: origin
    !> Load balancing: this rank's computing seconds (force evaluation and state updates) at
    !> the last look.
    real(wp) :: balance_mark = 0.0_wp
  contains
    procedure :: setup => simulation_setup
    procedure :: run => simulation_run
    procedure :: finish => simulation_finish
  end type simulation_t

  ! checkpoints and continued runs (iem_restart.f90)
  interface
    !> Check the checkpoint to continue from, whole, before anything is written.
    module subroutine check_restart(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine check_restart

    !> Write a checkpoint of the state at the top of step k (sig: the signal the run stops
    !> on); it becomes the run's origin.
    module subroutine write_checkpoint(this, k, t, sig, stat, msg)
      ! (target: its registry borrows the run's arrays)
      type(simulation_t), intent(inout), target :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(in) :: sig
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine write_checkpoint

    !> Read the checkpoint at path (its header h) into the run's checkpointed fields (the
    !> records by global index onto this rank's nodes and cells, the springs' and damage's
    !> derived state refreshed) and the model's exact work accumulators. Collective.
    module subroutine read_state(this, path, h, stat, msg)
      ! (target: its registry borrows the run's arrays)
      type(simulation_t), intent(inout), target :: this
      character(len=*), intent(in) :: path
      type(checkpoint_header_t), intent(in) :: h
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine read_state

    !> Restore the state of the checkpoint this run continues from.
    module subroutine load_checkpoint(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine load_checkpoint

    !> Whether checkpoint_if_due at step k (at t; the step before it at t_prev) looks at the
    !> state: it checks for a signal there, or a checkpoint interval ends there.
    module pure logical function checkpoint_looks(this, k, t_prev, t) result(looks)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t_prev, t
    end function checkpoint_looks

    !> At the top of step k > the first: write a checkpoint when one is due (its interval of
    !> simulated time since t_prev, or a signal, polled every check_interval steps); after a
    !> signal stop with stat = 4. Collective.
    module subroutine checkpoint_if_due(this, k, t, t_prev, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t, t_prev
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine checkpoint_if_due

    !> Register the run's per-node and per-cell state (the one list, iem_simulation_fields)
    !> in reg for this rank's nodes and cells, all of it or, with checkpoint, what a
    !> checkpoint holds, and copy it in; with borrow, reg borrows the run's arrays that span
    !> its entities instead of copying them (reg must then go before they change size or
    !> move: no resize, reset, permute or migration). stat /= 0 when a field could not be
    !> added (memory).
    module subroutine state_to_registry(this, reg, checkpoint, stat, borrow)
      type(simulation_t), intent(inout), target :: this
      type(field_registry_t), intent(inout), target :: reg
      logical, intent(in) :: checkpoint
      integer, intent(out) :: stat
      logical, intent(in), optional :: borrow
    end subroutine state_to_registry

    !> Copy the fields reg holds back into the run's arrays (sized for reg's entities; a node
    !> field of owned nodes only fills its array's n_owned columns).
    module subroutine state_from_registry(this, reg)
      type(simulation_t), intent(inout) :: this
      type(field_registry_t), intent(inout), target :: reg
    end subroutine state_from_registry

    !> The same registration with no nodes and no cells: the record layout alone.
    module subroutine state_layout(this, reg, checkpoint, stat)
      type(simulation_t), intent(inout) :: this
      type(field_registry_t), intent(inout), target :: reg
      logical, intent(in) :: checkpoint
      integer, intent(out) :: stat
    end subroutine state_layout

    !> Reopen the output of the interrupted run to append to it.
    module subroutine reopen_output(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine reopen_output

    ! the set-up, output, static run, guards and reports of a run (iem_simulation_setup,
    ! _output, _static, _guards, _report)
    !> Build everything for the run; collective; stat /= 0 with msg on every rank on an error
    !> found before any output is written.
    module subroutine simulation_setup(this, cfg, comm, stat, msg)
      class(simulation_t), intent(inout) :: this
      type(config_t), intent(in) :: cfg
      type(MPI_Comm), intent(in) :: comm
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine simulation_setup

    !> Allocate the state (with the work arrays the integrator needs), all ranks agreeing; set
    !> the initial state (its velocities, the prescribed dofs at t = 0).
    module subroutine allocate_state(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine allocate_state

    !> The initial velocity field of &initial: uniform velocity plus a rigid spin (the filtered
    !> velocity of capped damping starts equal to it).
    module subroutine initial_velocity(this)
      type(simulation_t), intent(inout) :: this
    end subroutine initial_velocity

    !> Recompute the partition at step k (the bisection with new node weights, or with the
    !> ranks' parts in proportion to share) and move every node's state and every cell's
    !> history to its new rank; rebuild the model, the state arrays, the probes' places and
    !> the output's selections for the new lattice. Collective.
    module subroutine repartition_run(this, k, stat, msg, share)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
      real(wp), intent(in), optional :: share(0:)
    end subroutine repartition_run

    !> Load balancing at step k: compare the ranks' computing time since the last look and,
    !> when the slowest exceeds the mean by more than balance_tolerance, repartition with each
    !> rank's part in proportion to its speed (repartition_run). Collective.
    module subroutine balance_run(this, k, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine balance_run

    !> Create the output file, or reopen that of the interrupted run when continuing one.
    module subroutine open_output(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine open_output

    !> Global indices of this rank's counted cells, ascending.
    module function counted_cell_gids(this) result(g)
      type(simulation_t), intent(in) :: this
      integer(i8), allocatable :: g(:)
    end function counted_cell_gids

    !> Gather one history sample (global sums with one Allreduce) into the buffer.
    module subroutine record_sample(this, k, t, diverged)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      logical, intent(out) :: diverged
    end subroutine record_sample

    !> Write the buffered history samples to the file.
    module subroutine flush_history(this, stat)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
    end subroutine flush_history

    !> True when a multiple of interval lies in (t_prev, t] (always when t_prev < 0): whether
    !> a sample, frame or checkpoint with that interval is due at t.
    module pure logical function crossed(t_prev, t, interval)
      real(wp), intent(in) :: t_prev, t, interval
    end function crossed

    !> Write a frame of the state at step k (and the cells' degree of nonlinearity).
    module subroutine write_frame(this, k, t, stat)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(out) :: stat
    end subroutine write_frame

    !> The time loop of a dynamic run, from step 0 or the checkpoint it continues from, to
    !> n_steps: at the top of each step a checkpoint when due, the integrator's rates, the
    !> guards, the history sample and the frame when due, progress; then the integrator's step.
    module subroutine run_dynamic(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine run_dynamic

    !> The load steps of a static run: relax to equilibrium at each pseudo-time t_k = k t_end/N
    !> (k = 0: the equilibrium at t = 0, usually the unloaded state), then record one history
    !> sample and one frame; stat /= 0 when a step does not converge or diverges.
    module subroutine run_static(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine run_static

    !> Stop on non-finite values at step k, first_bad being this rank's first owned node
    !> holding one (0: none; none on any rank: the energies were not finite): name the first
    !> node (lowest global index), its rank and position, and write the last good state
    !> good(:, n_owned) (rows 1:2 u, 3:4 v) of step k_good as a frame, note added to what
    !> the message says of it. Collective.
    module subroutine stop_nonfinite(this, k, t, first_bad, good, k_good, t_good, note, stat, &
                                     msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k, k_good
      real(wp), intent(in) :: t, t_good
      integer, intent(in) :: first_bad
      real(wp), intent(in), contiguous :: good(:, :)
      character(len=*), intent(in) :: note
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine stop_nonfinite

    !> Stop on a history sample at step k whose global sums are not finite, writing the last
    !> good state as the last frame. Collective.
    module subroutine stop_diverged(this, k, t, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine stop_diverged

    !> Stop on step k, which the integrator rejected (its new values are not finite somewhere;
    !> the integrator's last good state, of step k - 1 or of step k itself, is written as the
    !> last frame). Collective.
    module subroutine stop_rejected(this, k, t, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine stop_rejected

    !> Whether the ranks look at their balance at the top of step k (balance_interval, more
    !> than one rank, not the repartition step).
    module pure logical function balance_due(this, k)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
    end function balance_due

    !> Whether step k (at t; the step before it at t_prev) takes a history sample.
    module pure logical function sample_due(this, k, t_prev, t)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t_prev, t
    end function sample_due

    !> Whether step k (at t; the step before it at t_prev) writes a frame.
    module pure logical function frame_due(this, k, t_prev, t)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t_prev, t
    end function frame_due

    !> Before the step from step k (at t): say to the integrator and the model what the
    !> schedule does at steps k + 1 and k + 2 (t_next, next_plain, next_forces, energies_due).
    module subroutine plan_next(this, k, t)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
    end subroutine plan_next

    !> Whether nothing reads the state of step k (at t; the step before it at t_prev) before
    !> step k + 1 starts from it: k is not the last step, and at k the loop of run_dynamic
    !> takes no history sample, writes no frame, does not look for a checkpoint and does not
    !> repartition or look at the balance (the integrator may then leave the state part way
    !> into step k + 1).
    module pure logical function quiet_step(this, k, t_prev, t) result(quiet)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t_prev, t
    end function quiet_step

    !> Runs with the integrator's local: agree over the ranks on the first step rejected since
    !> the last agreement (before anything reads the state); with one, step again from the
    !> origin to it and stop there as stop_rejected does (stat = 3). Collective.
    module subroutine agree_steps(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine agree_steps

    !> Step k (at t) was rejected: with the integrator's local, on this rank alone, which keeps
    !> the first such step and lets the integrator go on stepping on finite values until the
    !> next agreement (stat = 0); else on every rank, which stop there (stop_rejected, stat =
    !> 3).
    module subroutine step_rejected(this, k, t, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine step_rejected

    !> Energy guard after a history sample: warn once above energy_warn, stop above
    !> energy_stop, naming the node with the largest speed (where a divergence grows fastest)
    !> and writing the current state as the last frame. Collective.
    module subroutine energy_guard(this, k, t, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine energy_guard

    !> Log the size of the run, its time step and its damping (rank 0).
    module subroutine report_start(this)
      type(simulation_t), intent(in) :: this
    end subroutine report_start

    !> Rank 0 reports throughput, where the time went (largest over ranks) and peak memory.
    module subroutine report_performance(this, wall)
      type(simulation_t), intent(in) :: this
      real(wp), intent(in) :: wall
    end subroutine report_performance

    !> Rank 0: print a progress line at every 10% of the run and every progress_interval s.
    module subroutine progress(this, k, t, wall0, wall_last, next_report)
      type(simulation_t), intent(in) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      real(wp), intent(inout) :: wall0, wall_last, next_report
    end subroutine progress

    !> 'RK4' or 'velocity Verlet': the integrator of a dynamic run, for messages.
    module function integrator_name(this) result(name)
      type(simulation_t), intent(in) :: this
      character(len=:), allocatable :: name
    end function integrator_name
  end interface

contains

  !> Create the output file, march to t_end, and close the file; stat /= 0 on failure.
  subroutine simulation_run(this, stat, msg)
    class(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    logical :: gradual

    ! a dynamic run checkpoints and stops on SIGTERM/SIGUSR1 from here on (a signal during
    ! the set-up is acted on at the first check of the time loop)
    if (.not. this%static) call install_signal_handlers()
    ! the set-up's freed pages go back to the system before the mesh output's buffers, and
    ! those before the state takes its own (else they stay resident and add to the peak)
    call heap_release()
    call open_output(this, stat, msg)
    if (stat /= 0) return
    call heap_release()
    call allocate_state(this, stat, msg)
    if (stat /= 0) return
    ! subnormal results flushed to zero while the solver runs (iem_underflow)
    call flush_subnormals(gradual)
    if (this%static) then
      call run_static(this, stat, msg)
    else
      call run_dynamic(this, stat, msg)
    end if
    call restore_underflow(gradual)
  end subroutine simulation_run

  !> Close the output (marking it complete when the run ended normally).
  subroutine simulation_finish(this, complete, stat, msg)
    class(simulation_t), intent(inout) :: this
    logical, intent(in) :: complete
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    stat = 0
    msg = ''
    if (this%output_open) then
      call this%out%close(complete, stat, msg)
      this%output_open = .false.
    end if
  end subroutine simulation_finish
end module iem_simulation
