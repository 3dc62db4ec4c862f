!> A whole run: set up the lattice, model and output from a validated configuration, then
!> march in time with RK4 or velocity Verlet (analysis = 'dynamic') or relax load step by load step (analysis =
!> 'static'), recording history, frames and progress.
module iem_simulation
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_SUM, MPI_MAX, &
                     MPI_IN_PLACE, MPI_Wtime, MPI_INTEGER8, MPI_LOGICAL, MPI_LAND, MPI_MIN, &
                     MPI_INTEGER, MPI_2DOUBLE_PRECISION, MPI_MAXLOC
  use iem_kinds, only: wp, i8, mpi_wp
  use iem_config, only: config_t, damping_config_t
  use iem_grid, only: grid_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_decomposition, only: decompose
  use iem_model, only: model_t
  use iem_state, only: state_t, state_rate
  use iem_rk4, only: rk4_finish_step
  use iem_verlet, only: verlet_step
  use iem_stable_dt, only: cell_omega_max, rk4_stable_dt, verlet_stable_dt
  use iem_relaxation, only: relaxation_t, relax_result_t, relax_check_interval
  use iem_cell_kernel, only: cell_strain_measures
  use iem_nonlinear_springs, only: springs_per_cell, spring_kind, spring_strains
  use iem_spring_constants, only: spring_moduli
  use iem_checkpoint, only: checkpoint_header_t
  use iem_signals, only: install_signal_handlers, signal_caught
  use iem_h5_output, only: h5_output_t
  use iem_build_info, only: iem_version
  use iem_constants, only: rk4_imag_limit
  use iem_logger, only: log_info, log_warn
  use iem_timers, only: timer_start, timer_stop, timer_total, timer_names, n_timers, t_output, &
                        peak_rss_bytes
  use iem_strings, only: itoa, rtoa
  use iem_limits, only: grid_limit_message, springs_limit_message, max_springs_per_rank
  use iem_memory, only: memory_case_t, memory_need_t, memory_estimate, memory_check
  use iem_alloc_guard, only: alloc_guard_t
  use iem_build_info, only: metis_idx
  implicit none
  private
  public :: simulation_t
  ! used by the submodule iem_restart: gfortran does not keep private module procedures that
  ! only a submodule calls
  public :: flush_history, counted_cell_gids

  integer, parameter :: n_energy = 5, history_chunk = 256

  !> One run: configuration, decomposition, model, state, output and the history buffer.
  type :: simulation_t
    type(MPI_Comm) :: comm
    integer :: rank = 0, n_ranks = 1
    type(config_t) :: cfg
    type(grid_t) :: grid
    type(local_lattice_t) :: lat
    type(halo_t) :: halo
    type(model_t) :: model
    type(state_t) :: st
    !> Dynamic relaxation of a static run.
    type(relaxation_t) :: relax
    logical :: static = .false.
    !> Dynamic runs: velocity Verlet instead of RK4.
    logical :: verlet = .false.
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
    !> Spring moduli (Eq, Hq, Gq): a spring's stress is its modulus times its normalised
    !> stress (its strain, when elastic).
    real(wp) :: moduli(3) = 0.0_wp
    !> Nonlinear runs: the degree of nonlinearity of each counted cell, for frames.
    real(wp), allocatable :: cell_degree(:)
    !> Static runs: load factor, iterations and relative residual of each buffered sample.
    real(wp), allocatable :: h_load(:), h_res(:)
    integer(i8), allocatable :: h_iter(:)
    real(wp), allocatable :: sample(:)
    real(wp) :: e0 = 0.0_wp, e_scale = 0.0_wp, last_balance = 0.0_wp
    real(wp) :: w_ext = 0.0_wp, w_damp = 0.0_wp
    logical :: output_open = .false.
    !> Guards: the owned (u, v) at the last check that found every value finite, its step and
    !> time; whether the energy warning has been given.
    real(wp), allocatable :: snap(:, :)
    integer(i8) :: snap_step = 0
    real(wp) :: snap_time = 0.0_wp
    logical :: warned = .false.
    !> Restart: the checkpoint's header (step 0: a fresh run).
    type(checkpoint_header_t) :: restart
    !> The last history sample written (time and the five energies) and the time of the last
    !> frame: a checkpoint records them to recognise its output on a restart.
    real(wp) :: last_sample(6) = 0.0_wp, last_frame_time = 0.0_wp
  contains
    procedure :: setup => simulation_setup
    procedure :: run => simulation_run
    procedure :: finish => simulation_finish
  end type simulation_t

  !> Most steps a dynamic run may take: 2^53, where the time t + dt stops advancing.
  real(wp), parameter :: max_steps = 9007199254740992.0_wp

  ! checkpoints and continued runs (iem_restart.f90)
  interface
    !> Check the checkpoint to continue from, whole, before anything is written.
    module subroutine check_restart(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine check_restart

    !> Write a checkpoint of the state at the top of step k (sig: the signal the run stops on).
    module subroutine write_checkpoint(this, k, t, sig, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer(i8), intent(in) :: k
      real(wp), intent(in) :: t
      integer, intent(in) :: sig
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine write_checkpoint

    !> Restore the state of the checkpoint this run continues from.
    module subroutine load_checkpoint(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine load_checkpoint

    !> Reopen the output of the interrupted run to append to it.
    module subroutine reopen_output(this, stat, msg)
      type(simulation_t), intent(inout) :: this
      integer, intent(out) :: stat
      character(len=:), allocatable, intent(out) :: msg
    end subroutine reopen_output
  end interface

contains

  !> Build everything for the run; collective; stat /= 0 with msg on every rank on an error
  !> found before any output is written.
  subroutine simulation_setup(this, cfg, comm, stat, msg)
    class(simulation_t), intent(inout) :: this
    type(config_t), intent(in) :: cfg
    type(MPI_Comm), intent(in) :: comm
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8), allocatable :: n_selected(:)
    integer :: k, np, nb, n_state, nsp, ci, cj, l, ierr
    integer(i8) :: most(1)
    real(wp) :: m_corner
    character(len=:), allocatable :: label
    type(alloc_guard_t) :: guard

    this%cfg = cfg
    this%static = cfg%run%analysis == 'static'
    this%verlet = .not. this%static .and. cfg%run%integrator == 'verlet'
    if (this%static) then
      ! a static run has no damping: relaxation brings its own
      if (cfg%damping%kind /= 'none') call log_warn('&damping is ignored in a static analysis '// &
        '(dynamic relaxation damps its own fictitious motion)')
      this%cfg%damping = damping_config_t()
    end if
    this%comm = comm
    ! volumetric locking of the paper's cell: its Poisson springs grow like 1/(1 - nu'^2)
    if (cfg%geometry%cell == 'paper' .and. cfg%geometry%plane == 'strain' .and. &
        cfg%material%poisson >= 0.45_wp) call log_warn("nu = "// &
      rtoa(cfg%material%poisson)//" in plane strain: the paper's cell locks (too stiff "// &
      "in bending: by 14% at nu = 0.45, 40% at 0.49, 86% at 0.499 with 8 cells through the "// &
      "depth, docs/stability.md); cell = 'bending' does not")
    call MPI_Comm_rank(comm, this%rank)
    call MPI_Comm_size(comm, this%n_ranks)
    associate(g => cfg%geometry)
      call this%grid%init(g%length, g%height, g%thickness, g%nx, g%ny)
    end associate

    ! time step: cell-level bound of omega_max, damping included
    m_corner = 0.25_wp*cfg%material%density*this%grid%lx*this%grid%ly*this%grid%thickness
    ! capped damping carries the filtered velocity as two more state values a node
    n_state = 4
    if (this%cfg%damping%kind == 'capped') n_state = 6
    ! before anything is allocated: what this build can represent, and the memory it needs
    label = trim(cfg%input_file)//': '//this%grid%label()
    if (cfg%geometry%cell_size > 0.0_wp) label = label//' (from cell_size = '// &
      rtoa(cfg%geometry%cell_size)//')'
    msg = grid_limit_message(this%grid, this%n_ranks, cfg%material%nonlinear, label)
    stat = merge(1, 0, len(msg) > 0)
    if (stat /= 0) return
    call check_memory(this, n_state, label, stat, msg)
    if (stat /= 0) return
    call decompose(this%grid, comm, this%lat, this%halo, stat, msg, n_state)
    if (stat /= 0) return
    ! the same limits for the cells and nodes the ranks hold now: the largest over them
    most = 12_i8*this%lat%n_cells
    call MPI_Allreduce(MPI_IN_PLACE, most, 1, MPI_INTEGER8, MPI_MAX, comm)
    if (cfg%material%nonlinear .and. most(1) > max_springs_per_rank) then
      msg = springs_limit_message(label, most(1), this%grid%n_cells)
    end if
    stat = merge(1, 0, len(msg) > 0)
    if (stat /= 0) return
    nb = size(cfg%bcs)
    allocate(n_selected(nb + size(cfg%loads)))
    call this%model%init(this%cfg, this%grid, this%lat, n_selected, guard)
    call guard%agree(comm, label, stat, msg)
    if (stat /= 0) return
    call MPI_Allreduce(MPI_IN_PLACE, n_selected, size(n_selected), MPI_INTEGER8, MPI_SUM, comm)
    do k = 1, size(n_selected)
      if (n_selected(k) == 0) then
        stat = 1
        if (k <= nb) then
          msg = trim(cfg%input_file)//': &bc #'//itoa(k)//" ('"//trim(cfg%bcs(k)%name)// &
                "'): where = '"//trim(cfg%bcs(k)%set%where)//"' selects no node"
        else
          msg = trim(cfg%input_file)//': &load #'//itoa(k - nb)//" ('"// &
                trim(cfg%loads(k - nb)%name)//"'): where = '"// &
                trim(cfg%loads(k - nb)%set%where)//"' selects no node"
        end if
        return
      end if
    end do
    this%omega_max = cell_omega_max(this%model%k, m_corner)
    if (this%static) then
      ! load steps along the pseudo-time of the load path; dt is one load step's length
      call this%relax%init(this%model, this%lat, comm, cfg%static, cfg%run%t_end, guard)
      call guard%agree(comm, label, stat, msg)
      if (stat /= 0) return
      this%n_steps = cfg%static%load_steps
      this%dt = cfg%run%t_end/real(this%n_steps, wp)
    else
      if (this%verlet) then
        this%dt_limit = verlet_stable_dt(this%omega_max, this%model%alpha, this%model%beta, &
                                         this%model%omega_cap)
      else
        this%dt_limit = rk4_stable_dt(this%omega_max, this%model%alpha, this%model%beta, &
                                      this%model%omega_cap)
      end if
      if (cfg%run%dt > 0.0_wp) then
        if (cfg%run%dt > this%dt_limit .and. cfg%run%allow_unstable_dt) then
          call log_warn('&run: dt = '//rtoa(cfg%run%dt)//' s is '// &
            rtoa(cfg%run%dt/this%dt_limit)//' times the stability limit '// &
            rtoa(this%dt_limit)//' s of '//integrator_name(this)// &
            ' (allow_unstable_dt = .true.): expect the run to diverge; the guards will stop it')
        else if (cfg%run%dt > this%dt_limit) then
          stat = 1
          msg = trim(cfg%input_file)//': &run: dt = '//rtoa(cfg%run%dt)// &
                ' s is above the stability limit '//rtoa(this%dt_limit)// &
                ' s of '//integrator_name(this)//' for this grid and damping (omega_max = '// &
                rtoa(this%omega_max)// &
                ' rad/s); use dt <= '//rtoa(this%dt_limit)//' or dt = 0 (automatic), or '// &
                'allow_unstable_dt = .true. to run it anyway'
          return
        end if
        this%dt = cfg%run%dt
      else
        this%dt = cfg%run%dt_safety*this%dt_limit
      end if
      ! whole number of steps to t_end: dt only shrinks; a count past 2^53 cannot be kept in
      ! the step counter's double-precision time (t + dt == t), nor run
      if (.not. (this%dt > 0.0_wp .and. cfg%run%t_end/this%dt <= max_steps)) then
        stat = 1
        msg = trim(cfg%input_file)//': &run: t_end = '//rtoa(cfg%run%t_end)//' s needs '// &
              rtoa(cfg%run%t_end/this%dt)//' steps of dt = '//rtoa(this%dt)//' s (omega_max = '// &
              rtoa(this%omega_max)//' rad/s): more than 2^53 steps cannot be represented; '// &
              'shorten t_end or coarsen the grid'
        return
      end if
      this%n_steps = max(1_i8, ceiling(cfg%run%t_end/this%dt*(1.0_wp - 1.0e-12_wp), i8))
      this%dt = cfg%run%t_end/real(this%n_steps, wp)
      if (len_trim(cfg%run%restart) > 0) then
        call check_restart(this, stat, msg)
        if (stat /= 0) return
      end if
    end if

    ! probes
    np = size(cfg%probes)
    allocate(this%probe_gid(np), this%probe_local(np))
    do k = 1, np
      this%probe_gid(k) = this%grid%nearest_node(cfg%probes(k)%x, cfg%probes(k)%y)
      this%probe_local(k) = findloc(this%lat%gid(1:this%lat%n_owned), this%probe_gid(k), 1)
    end do

    ! spring probes: the cell that holds the point (the last cell on the far edges)
    this%moduli = spring_moduli(cfg%material%young, cfg%material%poisson, &
                                cfg%geometry%plane == 'strain')
    nsp = count(cfg%probes(:)%springs)
    allocate(this%sp_probe(nsp), this%sp_local(nsp), this%sp_cell(nsp))
    nsp = 0
    do k = 1, np
      if (.not. cfg%probes(k)%springs) cycle
      nsp = nsp + 1
      this%sp_probe(nsp) = k
      ci = min(max(int(cfg%probes(k)%x/this%grid%lx), 0), this%grid%nx - 1)
      cj = min(max(int(cfg%probes(k)%y/this%grid%ly), 0), this%grid%ny - 1)
      this%sp_cell(nsp) = int(ci, i8) + int(cj, i8)*this%grid%nx
      this%sp_local(nsp) = 0
      do l = 1, this%lat%n_cells
        if (this%lat%cell_gid(l) == this%sp_cell(nsp) .and. this%lat%cell_counted(l)) &
          this%sp_local(nsp) = l
      end do
    end do
    allocate(this%h_sp_e(springs_per_cell, nsp, history_chunk))
    allocate(this%h_sp_s(springs_per_cell, nsp, history_chunk))
    if (this%model%nonlinear) then
      allocate(this%cell_degree(this%lat%n_counted()), stat=ierr)
      call guard%note(ierr, 'the degree of nonlinearity of the cells', 8.0_wp*this%lat%n_cells)
    end if
    call guard%agree(comm, label, stat, msg)
    if (stat /= 0) return
    allocate(this%h_time(history_chunk), this%h_step(history_chunk))
    allocate(this%h_energy(n_energy, history_chunk))
    allocate(this%h_pu(2, np, history_chunk), this%h_pv(2, np, history_chunk))
    allocate(this%h_load(history_chunk), this%h_res(history_chunk), this%h_iter(history_chunk))
    allocate(this%sample(4 + 4*np + 2*springs_per_cell*nsp))
    stat = 0
    msg = ''
  end subroutine simulation_setup

  !> Refuse (stat = 1, msg) a run whose estimated memory exceeds what its nodes have (before
  !> anything problem-sized is allocated); log the estimate. Collective.
  subroutine check_memory(this, n_state, label, stat, msg)
    type(simulation_t), intent(in) :: this
    integer, intent(in) :: n_state
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: info
    type(memory_case_t) :: mc
    type(memory_need_t) :: need
    mc%n_nodes = this%grid%n_nodes
    mc%n_cells = this%grid%n_cells
    mc%n_ranks = this%n_ranks
    mc%n_state = n_state
    mc%integrator = 'rk4'
    if (this%verlet) mc%integrator = 'verlet'
    if (this%static) mc%integrator = 'static'
    mc%nonlinear = this%cfg%material%nonlinear
    mc%depth = this%cfg%material%history_depth
    mc%idx_bytes = storage_size(1_metis_idx)/8
    need = memory_estimate(mc)
    call memory_check(this%comm, need, label, stat, msg, info)
    if (stat == 0) call log_info(info)
  end subroutine check_memory

  !> Create the output file, march to t_end, and close the file; stat /= 0 on failure.
  subroutine simulation_run(this, stat, msg)
    class(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8) :: k, k_first
    integer :: sig, ierr
    real(wp) :: t, t_prev, wall0, wall_last, next_report
    logical :: diverged, finite, due
    type(alloc_guard_t) :: guard

    ! a dynamic run checkpoints and stops on SIGTERM/SIGUSR1 from here on (a signal during
    ! the set-up is acted on at the first check of the time loop)
    if (.not. this%static) call install_signal_handlers()
    call open_output(this, stat, msg)
    if (stat /= 0) return
    ! the state is allocated only now, after the mesh output's temporaries are gone, so that
    ! they do not add to the peak memory
    call this%st%init(this%lat%n_owned, this%lat%n_local, this%model%n_state, &
                      rk4_work=.not. (this%static .or. this%verlet), guard=guard)
    if (.not. this%static) then
      ! Verlet updates the state in place: the guard keeps a copy of the last good one; RK4
      ! checks each new state before accepting it and needs none
      allocate(this%snap(4, merge(this%lat%n_owned, 0, this%verlet)), stat=ierr)
      call guard%note(ierr, 'the copy of the last good state', 32.0_wp*this%lat%n_owned)
    end if
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    if (.not. this%static) then
      this%snap = 0.0_wp
      call initial_velocity(this)
    end if
    call this%model%prescribe(this%st%y, 0.0_wp)
    if (this%static) then
      call run_static(this, stat, msg)
      return
    end if
    call report_start(this)
    wall0 = MPI_Wtime()
    wall_last = wall0
    next_report = 0.1_wp
    t_prev = -1.0_wp
    this%w_ext = 0.0_wp
    this%w_damp = 0.0_wp
    k_first = 0
    if (this%restart%step > 0) then
      call load_checkpoint(this, stat, msg)
      if (stat /= 0) return
      k_first = this%restart%step
      t_prev = real(k_first - 1, wp)*this%dt
      next_report = real(floor(10.0_wp*real(k_first, wp)/real(this%n_steps, wp)) + 1, wp)/10.0_wp
      call log_info('continuing from '//trim(this%cfg%run%restart)//' at step '// &
                    itoa(k_first)//', t = '//rtoa(real(k_first, wp)*this%dt)//' s')
    end if
    do k = k_first, this%n_steps
      t = real(k, wp)*this%dt
      ! checkpoints: at their interval, and when the scheduler signals the end of the job
      if (k > k_first) then
        sig = 0
        if (mod(k, int(this%cfg%run%check_interval, i8)) == 0) then
          sig = signal_caught()
          call MPI_Allreduce(MPI_IN_PLACE, sig, 1, MPI_INTEGER, MPI_MAX, this%comm)
        end if
        due = sig /= 0
        ! (no short-circuit in Fortran: test the interval before dividing by it)
        if (this%cfg%run%checkpoint_interval > 0.0_wp) then
          if (crossed(t_prev, t, this%cfg%run%checkpoint_interval)) due = .true.
        end if
        if (due) then
          call write_checkpoint(this, k, t, sig, stat, msg)
          if (stat /= 0) return
          if (sig /= 0) then
            stat = 4
            msg = 'stopped by signal '//itoa(sig)//' at step '//itoa(k)//', t = '//rtoa(t)// &
                  ' s, after writing the checkpoint '//trim(this%cfg%run%checkpoint_file)// &
                  '; continue with restart = '''//trim(this%cfg%run%checkpoint_file)//''''
            return
          end if
        end if
      end if
      ! the rates at y(t): Verlet's last step has evaluated them already
      if (k == 0 .or. .not. this%verlet) call state_rate(this%model, this%lat, this%halo, &
                                                         this%st, t)
      if (this%verlet .and. mod(k, int(this%cfg%run%check_interval, i8)) == 0) then
        call check_state(this, k, t, stat, msg)
        if (stat /= 0) return
      end if
      if (k == 0 .or. k == this%n_steps .or. &
          crossed(t_prev, t, this%cfg%run%history_interval)) then
        call record_sample(this, k, t, diverged)
        if (diverged) then
          if (this%verlet) then
            call stop_nonfinite(this, k, t, this%st%y, this%snap, this%snap_step, &
                                this%snap_time, stat, msg)
          else
            ! RK4 accepted only finite states: the energies overflowed
            call stop_nonfinite(this, k, t, this%st%y, this%st%y(1:4, 1:this%lat%n_owned), &
                                k, t, stat, msg)
          end if
          return
        end if
        call energy_guard(this, k, t, stat, msg)
        if (stat /= 0) return
      end if
      if (k == 0 .or. k == this%n_steps .or. &
          crossed(t_prev, t, this%cfg%run%output_interval)) then
        call timer_start(t_output)
        call flush_history(this, stat)
        if (stat == 0) call write_frame(this, k, t, stat)
        call timer_stop(t_output)
        if (stat /= 0) then
          msg = 'writing output to '//trim(this%cfg%run%output_file)//' failed'
          return
        end if
      end if
      if (this%rank == 0) call progress(this, k, t, wall0, wall_last, next_report)
      if (k == this%n_steps) exit
      if (this%verlet) then
        call verlet_step(this%model, this%lat, this%halo, this%st, t, this%dt, &
                         this%w_ext, this%w_damp)
      else
        call rk4_finish_step(this%model, this%lat, this%halo, this%st, t, this%dt, &
                             this%w_ext, this%w_damp, finite)
        call MPI_Allreduce(MPI_IN_PLACE, finite, 1, MPI_LOGICAL, MPI_LAND, this%comm)
        if (.not. finite) then
          ! the step is not accepted: y still holds the last good state, that of step k
          call stop_nonfinite(this, k + 1, t + this%dt, this%st%ynew, &
                              this%st%y(1:4, 1:this%lat%n_owned), k, t, stat, msg)
          return
        end if
      end if
      t_prev = t
    end do
    call flush_history(this, stat)
    if (stat /= 0) then
      msg = 'writing the history to '//trim(this%cfg%run%output_file)//' failed'
      return
    end if
    call log_info('done: '//itoa(this%n_steps)//' steps in '//rtoa(MPI_Wtime() - wall0)// &
                  ' s wall; final energy-balance error '//rtoa(this%last_balance))
    call report_performance(this, MPI_Wtime() - wall0)
  end subroutine simulation_run

  !> Rank 0 reports throughput, where the time went (largest over ranks) and peak memory.
  subroutine report_performance(this, wall)
    type(simulation_t), intent(in) :: this
    real(wp), intent(in) :: wall
    real(wp) :: t(n_timers), mem(2), work
    character(len=300) :: line
    character(len=8) :: pct
    integer :: k
    do k = 1, n_timers
      t(k) = timer_total(k)
    end do
    call MPI_Allreduce(MPI_IN_PLACE, t, n_timers, mpi_wp(), MPI_MAX, this%comm)
    mem = real(peak_rss_bytes(), wp)/1048576.0_wp
    call MPI_Allreduce(MPI_IN_PLACE, mem(1), 1, mpi_wp(), MPI_MAX, this%comm)
    call MPI_Allreduce(MPI_IN_PLACE, mem(2), 1, mpi_wp(), MPI_SUM, this%comm)
    work = real(this%grid%n_nodes, wp)*real(this%n_steps, wp)
    write(line, '(a,es10.3,a,es10.3,a,es10.3,a,es10.3,a)') 'performance: ', work, &
      ' node-steps in ', wall, ' s: ', work/wall, ' node-steps/s (', &
      work/wall/this%n_ranks, ' per rank)'
    call log_info(trim(line))
    line = 'time in'
    do k = 1, n_timers
      write(pct, '(f6.1)') 100.0_wp*t(k)/wall
      line = trim(line)//' '//trim(timer_names(k))//' '//trim(adjustl(pct))//'%'
      if (k < n_timers) line = trim(line)//','
    end do
    call log_info(trim(line)//' (largest over ranks)')
    write(line, '(a,f0.1,a,f0.1,a)') 'memory: peak ', max(mem(1), 0.1_wp), &
      ' MB per rank (largest), ', max(mem(2), 0.1_wp), ' MB in all'
    call log_info(trim(line))
  end subroutine report_performance

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

  !> True when a multiple of interval lies in (t_prev, t].
  pure logical function crossed(t_prev, t, interval)
    real(wp), intent(in) :: t_prev, t, interval
    crossed = floor(t/interval*(1.0_wp + 1.0e-12_wp)) > floor(t_prev/interval*(1.0_wp + 1.0e-12_wp))
    if (t_prev < 0.0_wp) crossed = .true.
  end function crossed

  subroutine open_output(this, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    if (this%restart%step > 0) then
      call reopen_output(this, stat, msg)
    else
      call create_output(this, stat, msg)
    end if
  end subroutine open_output

  !> Global indices of this rank's counted cells, ascending.
  function counted_cell_gids(this) result(g)
    type(simulation_t), intent(in) :: this
    integer(i8), allocatable :: g(:)
    integer :: l, k
    allocate(g(this%lat%n_counted()))
    k = 0
    do l = 1, this%lat%n_cells
      if (.not. this%lat%cell_counted(l)) cycle
      k = k + 1
      g(k) = this%lat%cell_gid(l)
    end do
  end function counted_cell_gids

  subroutine create_output(this, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=64), allocatable :: names(:), sp_names(:)
    real(wp), allocatable :: pxy(:, :), nxy(:, :), sp_xy(:, :)
    integer(i8), allocatable :: cells(:, :), cell_gids(:)
    real(wp), allocatable :: coords(:, :)
    integer :: k, l, nc, ierr
    integer(i8) :: nodes(4)
    type(alloc_guard_t) :: guard

    associate(p => this%cfg%probes)
      allocate(names(size(p)), pxy(2, size(p)), nxy(2, size(p)))
      do k = 1, size(p)
        names(k) = p(k)%name
        pxy(:, k) = [p(k)%x, p(k)%y]
        nxy(:, k) = this%grid%node_xy(this%probe_gid(k))
      end do
    end associate
    call this%out%create(trim(this%cfg%run%output_file), this%comm, this%cfg%run%overwrite, &
      iem_version, trim(this%cfg%input_file), this%cfg%input_text, trim(this%cfg%run%analysis), &
      this%grid%n_nodes, this%grid%n_cells, this%lat%gid(1:this%lat%n_owned), names, pxy, &
      this%probe_gid, nxy, stat, msg)
    if (stat /= 0) return
    this%output_open = .true.
    nc = this%lat%n_counted()
    allocate(coords(2, this%lat%n_owned), cells(4, nc), cell_gids(nc), stat=ierr)
    call guard%note(ierr, 'the mesh output buffers', 16.0_wp*this%lat%n_owned + 40.0_wp*nc)
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    do l = 1, this%lat%n_owned
      coords(:, l) = this%grid%node_xy(this%lat%gid(l))
    end do
    k = 0
    do l = 1, this%lat%n_cells
      if (.not. this%lat%cell_counted(l)) cycle
      k = k + 1
      nodes = this%lat%gid(this%lat%cell_nodes(:, l))
      cells(:, k) = nodes
      cell_gids(k) = this%lat%cell_gid(l)
    end do
    call this%out%write_mesh(coords, this%model%mass, cells, cell_gids, this%grid%nx, &
      this%grid%ny, this%grid%lx, this%grid%ly, this%grid%thickness, &
      trim(this%cfg%geometry%plane), stat, msg)
    if (stat /= 0) return
    if (size(this%sp_probe) > 0) then
      allocate(sp_names(size(this%sp_probe)), sp_xy(2, size(this%sp_probe)))
      do k = 1, size(this%sp_probe)
        sp_names(k) = this%cfg%probes(this%sp_probe(k))%name
        sp_xy(:, k) = [this%cfg%probes(this%sp_probe(k))%x, this%cfg%probes(this%sp_probe(k))%y]
      end do
      call this%out%define_spring_probes(sp_names, this%sp_cell, sp_xy, stat, msg)
      if (stat /= 0) return
    end if
    if (.not. this%static) return
    associate(s => this%cfg%static)
      call this%out%write_static_settings(s%load_steps, s%tolerance, s%max_iterations, &
        trim(s%method), trim(s%mass), relax_check_interval, stat, msg)
    end associate
  end subroutine create_output

  !> Gather one history sample (global sums with one Allreduce) into the buffer.
  subroutine record_sample(this, k, t, diverged)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k
    real(wp), intent(in) :: t
    logical, intent(out) :: diverged
    integer :: p, np, b, stat, o
    real(wp) :: ke, se, e, scale

    np = size(this%probe_gid)
    this%sample = 0.0_wp
    this%sample(1) = this%model%kinetic_energy(this%st%y)
    this%sample(2) = this%model%strain_energy()
    this%sample(3) = this%w_ext
    this%sample(4) = this%w_damp
    do p = 1, np
      if (this%probe_local(p) > 0) then
        this%sample(4 + 4*(p - 1) + 1:4 + 4*p) = this%st%y(1:4, this%probe_local(p))
      end if
    end do
    o = 4 + 4*np
    do p = 1, size(this%sp_probe)
      if (this%sp_local(p) > 0) call spring_sample(this, this%sp_local(p), &
        this%sample(o + 1:o + springs_per_cell), &
        this%sample(o + springs_per_cell + 1:o + 2*springs_per_cell))
      o = o + 2*springs_per_cell
    end do
    call MPI_Allreduce(MPI_IN_PLACE, this%sample, size(this%sample), mpi_wp(), MPI_SUM, this%comm)
    diverged = .not. all(ieee_is_finite(this%sample))
    if (diverged) return
    if (this%n_buf == history_chunk) call flush_history(this, stat)
    b = this%n_buf + 1
    this%n_buf = b
    ke = this%sample(1)
    se = this%sample(2)
    e = ke + se
    if (k == 0) then
      this%e0 = e
      this%e_scale = 0.0_wp
    end if
    ! scale: the largest energy the run has held so far, so that the error stays meaningful
    ! when the current energy passes through zero
    this%e_scale = max(this%e_scale, abs(this%sample(3)), e, this%sample(4))
    scale = max(this%e_scale, tiny(1.0_wp))
    this%last_balance = abs(e + this%sample(4) - this%sample(3) - this%e0)/scale
    if (k == 0) this%last_balance = 0.0_wp
    this%h_time(b) = t
    this%h_step(b) = k
    this%h_energy(:, b) = [ke, se, this%sample(3), this%sample(4), this%last_balance]
    this%last_sample(1) = t
    this%last_sample(2:6) = this%h_energy(:, b)
    do p = 1, np
      this%h_pu(:, p, b) = this%sample(4 + 4*(p - 1) + 1:4 + 4*(p - 1) + 2)
      this%h_pv(:, p, b) = this%sample(4 + 4*(p - 1) + 3:4 + 4*p)
    end do
    o = 4 + 4*np
    do p = 1, size(this%sp_probe)
      this%h_sp_e(:, p, b) = this%sample(o + 1:o + springs_per_cell)
      this%h_sp_s(:, p, b) = this%sample(o + springs_per_cell + 1:o + 2*springs_per_cell)
      o = o + 2*springs_per_cell
    end do
  end subroutine record_sample

  !> Degree of nonlinearity of each counted cell at the committed state: the smallest secant
  !> over initial stiffness of its 12 springs (1: elastic; towards 0: far into the nonlinear
  !> range). Each spring's secant psi/e is clipped to [0, 1] (after a reversal the stress can
  !> pass zero before the strain does); a spring at zero strain counts as 1.
  subroutine nonlinearity_degree(this)
    type(simulation_t), intent(inout) :: this
    integer :: c, k, j, i
    real(wp) :: d, e
    k = 0
    do c = 1, this%lat%n_cells
      if (.not. this%lat%cell_counted(c)) cycle
      k = k + 1
      d = 1.0_wp
      do j = 1, springs_per_cell
        i = springs_per_cell*(c - 1) + j
        e = this%model%nl%state%strain(i)
        if (e /= 0.0_wp) d = min(d, max(0.0_wp, min(1.0_wp, this%model%nl%state%stress(i)/e)))
      end do
      this%cell_degree(k) = d
    end do
  end subroutine nonlinearity_degree

  !> Strains and stresses of the 12 springs of local cell c at the current state (committed:
  !> samples are taken at accepted states).
  subroutine spring_sample(this, c, strain, stress)
    type(simulation_t), intent(in) :: this
    integer, intent(in) :: c
    real(wp), intent(out) :: strain(springs_per_cell), stress(springs_per_cell)
    real(wp) :: u(2, 4), ep(4), sh(4)
    integer :: q, j
    do q = 1, 4
      u(:, q) = this%st%y(1:2, this%lat%cell_nodes(q, c))
    end do
    call cell_strain_measures(this%model%k, u, ep, sh)
    strain = spring_strains(ep, sh)
    do j = 1, springs_per_cell
      if (this%model%nonlinear) then
        stress(j) = this%moduli(spring_kind(j))* &
                    this%model%nl%state%stress(springs_per_cell*(c - 1) + j)
      else
        stress(j) = this%moduli(spring_kind(j))*strain(j)
      end if
    end do
  end subroutine spring_sample

  !> Write the buffered history samples to the file.
  subroutine flush_history(this, stat)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable :: msg
    integer :: n
    stat = 0
    n = this%n_buf
    if (n == 0 .or. .not. this%output_open) return
    if (this%static) then
      call this%out%write_history(n, this%h_time(1:n), this%h_step(1:n), &
        this%h_energy(:, 1:n), this%h_pu(:, :, 1:n), this%h_pv(:, :, 1:n), stat, msg, &
        load_factor=this%h_load(1:n), iterations=this%h_iter(1:n), residual=this%h_res(1:n))
    else
      call this%out%write_history(n, this%h_time(1:n), this%h_step(1:n), &
        this%h_energy(:, 1:n), this%h_pu(:, :, 1:n), this%h_pv(:, :, 1:n), stat, msg)
    end if
    if (stat == 0 .and. size(this%sp_probe) > 0) call this%out%write_spring_history(n, &
      this%h_sp_e(:, :, 1:n), this%h_sp_s(:, :, 1:n), stat, msg)
    this%n_buf = 0
  end subroutine flush_history

  subroutine write_frame(this, k, t, stat)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k
    real(wp), intent(in) :: t
    integer, intent(out) :: stat
    character(len=:), allocatable :: msg
    integer :: n
    n = this%lat%n_owned
    ! the sections are copied to contiguous temporaries at output time only
    call this%out%write_frame(k, t, this%st%y(1:2, 1:n), this%st%y(3:4, 1:n), stat, msg)
    this%last_frame_time = t
    if (stat /= 0 .or. .not. this%model%nonlinear) return
    call nonlinearity_degree(this)
    call this%out%write_cell_field('nonlinearity', this%cell_degree, stat, msg)
  end subroutine write_frame

  !> The load steps of a static run: relax to equilibrium at each pseudo-time t_k = k t_end/N
  !> (k = 0: the equilibrium at t = 0, usually the unloaded state), then record one history
  !> sample and one frame; stat /= 0 when a step does not converge or diverges.
  subroutine run_static(this, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(relax_result_t) :: res
    integer(i8) :: k, total_iterations
    integer :: b, stat2
    real(wp) :: t, t_prev, wall0, wall_step
    logical :: diverged
    character(len=200) :: line

    associate(s => this%cfg%static)
      call log_info('iem '//iem_version//': '//itoa(this%grid%n_nodes)//' nodes, '// &
        itoa(this%grid%n_cells)//' cells ('//itoa(this%grid%nx)//' x '//itoa(this%grid%ny)// &
        '), '//itoa(this%n_ranks)//' ranks')
      call log_info('static analysis by dynamic relaxation: '//itoa(s%load_steps)// &
        ' load steps to t = '//rtoa(this%cfg%run%t_end)//', '//trim(s%method)// &
        ' damping, '//trim(s%mass)//' masses, tolerance '//rtoa(s%tolerance)// &
        ' (relative residual), at most '//itoa(s%max_iterations)//' iterations a step')
    end associate
    stat = 0
    msg = ''
    wall0 = MPI_Wtime()
    this%w_ext = 0.0_wp
    this%w_damp = 0.0_wp
    total_iterations = 0
    t_prev = 0.0_wp
    do k = 0, this%n_steps
      t = this%cfg%run%t_end*real(k, wp)/real(this%n_steps, wp)
      wall_step = MPI_Wtime()
      call this%relax%step(this%model, this%lat, this%halo, this%st%y, t_prev, t, res)
      total_iterations = total_iterations + res%iterations
      if (.not. (res%finite .and. res%converged)) then
        stat = 3
        if (.not. res%finite) then
          msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
                ') diverged (non-finite forces) after '//itoa(res%iterations)//' iterations'
        else
          msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
                ', load factor '//rtoa(res%load_factor)//') did not converge in '// &
                itoa(res%iterations)//' iterations: relative residual '// &
                rtoa(res%residual)//' > tolerance '//rtoa(this%cfg%static%tolerance)// &
                '; raise &static max_iterations, use more load_steps or a looser tolerance'
        end if
        call flush_history(this, stat2)
        return
      end if
      ! nonlinear springs have committed their history at the converged state (relax%step)
      this%w_ext = this%w_ext + res%work
      call record_sample(this, k, t, diverged)
      if (diverged) then
        stat = 3
        msg = 'static load step '//itoa(k)//'/'//itoa(this%n_steps)//' (t = '//rtoa(t)// &
              ') gave non-finite energies'
        call flush_history(this, stat2)
        return
      end if
      b = this%n_buf
      this%h_load(b) = res%load_factor
      this%h_iter(b) = res%iterations
      this%h_res(b) = res%residual
      call flush_history(this, stat)
      if (stat == 0) call write_frame(this, k, t, stat)
      if (stat /= 0) then
        msg = 'writing output to '//trim(this%cfg%run%output_file)//' failed'
        return
      end if
      write(line, '(a,i0,a,i0,a,f8.5,a,i8,a,es9.2,a,f9.2,a)') 'load step ', k, '/', &
        this%n_steps, '  load factor ', res%load_factor, '  iterations ', res%iterations, &
        '  residual ', res%residual, '  wall ', MPI_Wtime() - wall_step, ' s'
      call log_info(trim(line))
      t_prev = t
    end do
    call log_info('done: '//itoa(this%n_steps)//' load steps, '//itoa(total_iterations)// &
                  ' iterations in '//rtoa(MPI_Wtime() - wall0)//' s wall; energy-balance '// &
                  'error '//rtoa(this%last_balance))
  end subroutine run_static

  subroutine report_start(this)
    type(simulation_t), intent(in) :: this
    call log_info('iem '//iem_version//': '//itoa(this%grid%n_nodes)//' nodes, '// &
      itoa(this%grid%n_cells)//' cells ('//itoa(this%grid%nx)//' x '//itoa(this%grid%ny)// &
      '), '//itoa(this%n_ranks)//' ranks')
    call log_info('time step '//rtoa(this%dt)//' s = '// &
      rtoa(this%dt/this%dt_limit)//' of the '//integrator_name(this)//' limit '// &
      rtoa(this%dt_limit)// &
      ' s (omega_max '//rtoa(this%omega_max)//' rad/s); '//itoa(this%n_steps)//' steps to '// &
      rtoa(this%cfg%run%t_end)//' s')
    if (this%model%alpha > 0.0_wp .or. this%model%beta > 0.0_wp) then
      call log_info('Rayleigh damping: alpha = '//rtoa(this%model%alpha)//' 1/s, beta = '// &
                    rtoa(this%model%beta)//' s')
      if (this%model%omega_cap > 0.0_wp) call log_info('stiffness damping acts on the '// &
        'velocity filtered at '//rtoa(this%cfg%damping%cap_frequency)//' Hz (capped)')
      call log_info('damped stable step '//rtoa(this%dt_limit)//' s = '// &
        rtoa(this%dt_limit/undamped_limit(this))//' of the undamped one')
    end if
  end subroutine report_start

  !> The initial velocity field of &initial: uniform velocity plus a rigid spin (the filtered
  !> velocity of capped damping starts equal to it).
  subroutine initial_velocity(this)
    type(simulation_t), intent(inout) :: this
    integer :: l
    real(wp) :: xy(2)
    associate(ini => this%cfg%initial)
      do l = 1, this%lat%n_owned
        xy = this%grid%node_xy(this%lat%gid(l)) - ini%center
        this%st%y(3:4, l) = ini%velocity + ini%angular_velocity*[-xy(2), xy(1)]
        if (this%model%n_state == 6) this%st%y(5:6, l) = this%st%y(3:4, l)
      end do
    end associate
  end subroutine initial_velocity

  !> Guard at step k: every owned value finite (else stop with the last good frame); keep the
  !> state as the last good one; the energy balance against the thresholds. Collective.
  subroutine check_state(this, k, t, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k
    real(wp), intent(in) :: t
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: n
    logical :: finite
    stat = 0
    msg = ''
    n = this%lat%n_owned
    finite = all(ieee_is_finite(this%st%y(1:4, 1:n)))
    call MPI_Allreduce(MPI_IN_PLACE, finite, 1, MPI_LOGICAL, MPI_LAND, this%comm)
    if (.not. finite) then
      call stop_nonfinite(this, k, t, this%st%y, this%snap, this%snap_step, this%snap_time, &
                          stat, msg)
      return
    end if
    this%snap = this%st%y(1:4, 1:n)
    this%snap_step = k
    this%snap_time = t
  end subroutine check_state

  !> Stop on non-finite values in the state bad(:, owned nodes) of step k: name the first node
  !> (lowest global index) holding one, its rank and position, and write the last good state
  !> good(4, n_owned) of step k_good as a frame. Collective.
  subroutine stop_nonfinite(this, k, t, bad, good, k_good, t_good, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k, k_good
    real(wp), intent(in) :: t, t_good
    real(wp), intent(in) :: bad(:, :), good(:, :)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8) :: first, mine
    integer :: l, owner, stat2
    real(wp) :: xy(2), big(2)
    character(len=:), allocatable :: msg2
    mine = huge(1_i8)
    do l = 1, this%lat%n_owned
      if (.not. all(ieee_is_finite(bad(1:4, l)))) then
        mine = this%lat%gid(l)
        exit
      end if
    end do
    call MPI_Allreduce(mine, first, 1, MPI_INTEGER8, MPI_MIN, this%comm)
    owner = -1
    if (mine == first) owner = this%rank
    call MPI_Allreduce(MPI_IN_PLACE, owner, 1, MPI_INTEGER, MPI_MAX, this%comm)
    stat = 3
    if (first == huge(1_i8)) then
      msg = 'the solution diverged (non-finite energy) at step '//itoa(k)//', t = '//rtoa(t)//' s'
    else
      xy = this%grid%node_xy(first)
      msg = 'the solution diverged: non-finite values at step '//itoa(k)//', t = '//rtoa(t)// &
            ' s, first at node '//itoa(first)//' (x = '//rtoa(xy(1))//', y = '//rtoa(xy(2))// &
            ' m) on rank '//itoa(owner)
    end if
    ! where the growth was largest in the last good state
    big = [-1.0_wp, -1.0_wp]
    do l = 1, this%lat%n_owned
      if (norm2(good(3:4, l)) > big(1)) big = [norm2(good(3:4, l)), real(this%lat%gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, big, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, this%comm)
    xy = this%grid%node_xy(int(big(2), i8))
    msg = msg//', with dt = '//rtoa(this%dt)//' s (stability limit '//rtoa(this%dt_limit)// &
          ' s); in the last good state (step '//itoa(k_good)//', written as the last '// &
          'frame) the fastest node was '//itoa(int(big(2), i8))//' (x = '//rtoa(xy(1))// &
          ', y = '//rtoa(xy(2))//' m, speed '//rtoa(big(1))//' m/s)'
    call flush_history(this, stat2)
    call this%out%write_frame(k_good, t_good, good(1:2, :), good(3:4, :), stat2, msg2)
  end subroutine stop_nonfinite

  !> Energy guard after a history sample: warn once above energy_warn, stop above
  !> energy_stop, naming the node with the largest speed (where a divergence grows fastest)
  !> and writing the current state as the last frame. Collective.
  subroutine energy_guard(this, k, t, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k
    real(wp), intent(in) :: t
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    real(wp) :: err, fast(2), xy(2)
    integer :: l, stat2
    logical :: warn, halt
    character(len=:), allocatable :: where, msg2
    stat = 0
    msg = ''
    err = this%last_balance
    warn = this%cfg%run%energy_warn > 0.0_wp .and. err > this%cfg%run%energy_warn .and. &
           .not. this%warned
    halt = this%cfg%run%energy_stop > 0.0_wp .and. err > this%cfg%run%energy_stop
    if (.not. (warn .or. halt)) return
    ! the fastest node: (speed, global index) with MAXLOC
    fast = [-1.0_wp, -1.0_wp]
    do l = 1, this%lat%n_owned
      if (norm2(this%st%y(3:4, l)) > fast(1)) fast = [norm2(this%st%y(3:4, l)), &
                                                       real(this%lat%gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, fast, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, this%comm)
    xy = this%grid%node_xy(int(fast(2), i8))
    where = 'fastest node '//itoa(int(fast(2), i8))//' (x = '//rtoa(xy(1))//', y = '// &
            rtoa(xy(2))//' m, speed '//rtoa(fast(1))//' m/s)'
    if (halt) then
      stat = 3
      msg = 'energy-balance error '//rtoa(err)//' > energy_stop = '// &
            rtoa(this%cfg%run%energy_stop)//' at step '//itoa(k)//', t = '//rtoa(t)//' s; '// &
            where//'; dt = '//rtoa(this%dt)//' s (stability limit '//rtoa(this%dt_limit)// &
            ' s); the state at this step is the last frame'
      call flush_history(this, stat2)
      call write_frame(this, k, t, stat2)
      return
    end if
    this%warned = .true.
    call log_warn('energy-balance error '//rtoa(err)//' > energy_warn = '// &
                  rtoa(this%cfg%run%energy_warn)//' at step '//itoa(k)//', t = '//rtoa(t)// &
                  ' s; '//where//' (warned once; the run goes on)')
  end subroutine energy_guard

  !> 'RK4' or 'velocity Verlet': the integrator of a dynamic run, for messages.
  function integrator_name(this) result(name)
    type(simulation_t), intent(in) :: this
    character(len=:), allocatable :: name
    name = 'RK4'
    if (this%verlet) name = 'velocity Verlet'
  end function integrator_name

  !> The integrator's stable step without damping.
  real(wp) function undamped_limit(this) result(dt)
    type(simulation_t), intent(in) :: this
    dt = rk4_imag_limit/this%omega_max
    if (this%verlet) dt = 2.0_wp/this%omega_max
  end function undamped_limit

  !> Rank 0: print a progress line at every 10% of the run and every progress_interval s.
  subroutine progress(this, k, t, wall0, wall_last, next_report)
    type(simulation_t), intent(in) :: this
    integer(i8), intent(in) :: k
    real(wp), intent(in) :: t
    real(wp), intent(inout) :: wall0, wall_last, next_report
    real(wp) :: now, frac, eta
    character(len=200) :: line
    now = MPI_Wtime()
    frac = real(k, wp)/real(this%n_steps, wp)
    if (frac + 1.0e-12_wp < next_report .and. now - wall_last < this%cfg%run%progress_interval &
        .and. k /= this%n_steps) return
    do while (next_report <= frac + 1.0e-12_wp)
      next_report = next_report + 0.1_wp
    end do
    wall_last = now
    eta = 0.0_wp
    if (k > 0) eta = (now - wall0)*(1.0_wp - frac)/frac
    write(line, '(a,i0,a,i0,a,es10.3,a,es9.2,a,f9.1,a,f9.1,a,es9.2)') 'step ', k, '/', &
      this%n_steps, '  t ', t, ' s  dt ', this%dt, ' s  wall ', now - wall0, ' s  eta ', eta, &
      ' s  energy error ', this%last_balance
    call log_info(trim(line))
  end subroutine progress
end module iem_simulation
