!> Set-up of a run: checks of what this build and the machine can hold, the
!> decomposition, the model, the time step (or load steps), probes and spring probes, the
!> history buffer; and the initial velocity field.
submodule (iem_simulation) iem_simulation_setup
  use mpi_f08, only: MPI_Comm_rank, MPI_Comm_size, MPI_SUM, MPI_INTEGER8
  use iem_config, only: damping_config_t
  use iem_decomposition, only: decompose
  use iem_body_numbering, only: body_strip_t, number_body
  use iem_lattice_queries, only: nearest_node, cell_holding, resolve_point_sets
  use iem_pieces, only: count_pieces
  use iem_integrator_factory, only: integrator_create
  use iem_stable_dt, only: cell_omega_max
  use iem_nonlinear_springs, only: springs_per_cell
  use iem_spring_constants, only: spring_moduli
  use iem_logger, only: log_warn
  use iem_limits, only: grid_limit_message, springs_limit_message, max_springs_per_rank
  use iem_memory, only: memory_case_t, memory_need_t, memory_estimate, memory_check
  use iem_kinds, only: mpi_wp
  use iem_timers, only: peak_rss_bytes
  implicit none

  !> Samples of the history buffer (written when full and at every frame) and its energies.
  integer, parameter :: n_energy = 6, history_chunk = 256
  !> Most steps a dynamic run may take: 2^53, where the time t + dt stops advancing.
  real(wp), parameter :: max_steps = 9007199254740992.0_wp

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure simulation_setup
    integer(i8), allocatable :: n_selected(:)
    integer :: k, np, nb, n_state, nsp, ci, l, ierr
    integer(i8) :: most(1)
    real(wp) :: m_corner, wall_setup, peak(1)
    character(len=:), allocatable :: label
    character(len=80) :: line
    type(alloc_guard_t) :: guard
    type(body_strip_t) :: strip

    wall_setup = MPI_Wtime()
    this%cfg = cfg
    this%static = cfg%run%analysis == 'static'
    this%verlet = .not. this%static .and. cfg%run%integrator == 'verlet'
    if (.not. this%static) call integrator_create(cfg%run%integrator, comm, this%integ)
    if (this%static) then
      ! a static run has no damping: relaxation brings its own
      if (cfg%damping%kind /= 'none') call log_warn('&damping is ignored in a static analysis '// &
        '(dynamic relaxation damps its own fictitious motion)')
      this%cfg%damping = damping_config_t()
    end if
    this%comm = comm
    ! volumetric locking of the paper's cell: its Poisson springs grow like 1/(1 - nu'^2)
    do k = 1, size(cfg%materials)
      if (cfg%geometry%cell == 'paper' .and. cfg%geometry%plane == 'strain' .and. &
          cfg%materials(k)%poisson >= 0.45_wp) call log_warn("nu = "// &
        rtoa(cfg%materials(k)%poisson)//" in plane strain: the paper's cell locks (too "// &
        "stiff in bending: by 14% at nu = 0.45, 40% at 0.49, 86% at 0.499 with 8 cells "// &
        "through the depth, docs/stability.md); cell = 'bending' does not")
    end do
    call MPI_Comm_rank(comm, this%rank)
    call MPI_Comm_size(comm, this%n_ranks)
    associate(g => cfg%geometry)
      call this%grid%init(g%length, g%height, g%thickness, g%nx, g%ny)
    end associate

    ! capped damping carries the filtered velocity as two more state values a node
    n_state = 4
    if (this%cfg%damping%kind == 'capped') n_state = 6
    ! before anything is allocated: what this build can represent, and the memory it needs
    label = trim(cfg%input_file)//': '//this%grid%label()
    if (cfg%geometry%cell_size > 0.0_wp) label = label//' (from cell_size = '// &
      rtoa(cfg%geometry%cell_size)//')'
    msg = grid_limit_message(this%grid, this%n_ranks, any(cfg%materials(:)%nonlinear), label)
    stat = merge(1, 0, len(msg) > 0)
    if (stat /= 0) return
    call check_memory(this, n_state, label, stat, msg)
    if (stat /= 0) return
    ! the body: its description on every rank, numbered in strips (every rank agrees on its
    ! errors), then each rank's share of it
    call this%body%init(cfg, this%grid, stat, msg)
    if (stat == 0 .and. .not. this%body%uniform) &
      call number_body(this%body, cfg, comm, strip, stat, msg)
    if (stat /= 0) then
      msg = trim(cfg%input_file)//': '//msg
      return
    end if
    if (this%body%uniform) then
      call decompose(this%body, comm, this%lat, this%halo, stat, msg, n_state)
    else
      call decompose(this%body, comm, this%lat, this%halo, stat, msg, n_state, strip=strip)
    end if
    if (stat /= 0) return
    if (.not. this%body%uniform) &
      call count_pieces(this%lat, this%halo, comm, this%body%n_pieces, this%body%piece_xy, &
                        this%body%n_listed)
    call report_pieces(this, stat, msg)
    if (stat /= 0) return
    call report_partition(this)
    ! the nodes of 'point' sets
    call resolve_point_sets(this%cfg, this%grid, this%lat, comm)
    ! the same limits for the cells and nodes the ranks hold now: the largest over them
    most = 12_i8*this%lat%n_cells
    call MPI_Allreduce(MPI_IN_PLACE, most, 1, MPI_INTEGER8, MPI_MAX, comm)
    if (any(cfg%materials(:)%nonlinear) .and. most(1) > max_springs_per_rank) then
      msg = springs_limit_message(label, most(1), this%grid%n_cells)
    end if
    stat = merge(1, 0, len(msg) > 0)
    if (stat /= 0) return
    nb = size(cfg%bcs)
    allocate(n_selected(nb + size(cfg%loads)))
    call this%model%init(this%cfg, this%body, this%lat, n_selected, guard)
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
    ! time step: cell-level bound of omega_max (the largest over the materials), damping
    ! included
    this%omega_max = 0.0_wp
    do k = 1, size(cfg%materials)
      m_corner = 0.25_wp*cfg%materials(k)%density*this%grid%lx*this%grid%ly*this%grid%thickness
      this%omega_max = max(this%omega_max, cell_omega_max(this%model%ks(k), m_corner))
    end do
    if (this%static) then
      ! load steps along the pseudo-time of the load path; dt is one load step's length
      call this%relax%init(this%model, this%lat, comm, cfg%static, cfg%run%t_end, guard)
      call guard%agree(comm, label, stat, msg)
      if (stat /= 0) return
      this%n_steps = cfg%static%load_steps
      this%dt = cfg%run%t_end/real(this%n_steps, wp)
    else
      this%dt_limit = this%integ%stable_dt(this%omega_max, this%model%alpha, this%model%beta, &
                                           this%model%omega_cap)
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
      this%probe_gid(k) = nearest_node(this%grid, this%lat, comm, cfg%probes(k)%x, &
                                       cfg%probes(k)%y)
      this%probe_local(k) = this%lat%local_of(this%probe_gid(k))
    end do

    ! spring probes: the cell that holds the point (the last cell on the far edges)
    nsp = count(cfg%probes(:)%springs)
    allocate(this%sp_probe(nsp), this%sp_local(nsp), this%sp_cell(nsp), this%moduli(3, nsp))
    nsp = 0
    do k = 1, np
      if (.not. cfg%probes(k)%springs) cycle
      nsp = nsp + 1
      this%sp_probe(nsp) = k
      call cell_holding(this%grid, this%lat, comm, cfg%probes(k)%x, cfg%probes(k)%y, &
                        this%sp_cell(nsp), ci)
      if (this%sp_cell(nsp) < 0) then
        stat = 1
        msg = trim(cfg%input_file)//': &probe #'//itoa(k)//" ('"//trim(cfg%probes(k)%name)// &
              "'): springs = .true. at x, y = "//rtoa(cfg%probes(k)%x)//', '// &
              rtoa(cfg%probes(k)%y)//': the cell there is not in the body (void)'
        return
      end if
      this%moduli(:, nsp) = spring_moduli(cfg%materials(ci)%young, cfg%materials(ci)%poisson, &
                                          cfg%geometry%plane == 'strain')
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
    ! reactions (one series a &bc name) and fracture: their buffers; a sample's sums
    call reaction_series(this)
    allocate(this%h_react(2, size(this%series_names), history_chunk))
    allocate(this%xsums(6 + 2*size(this%series_names)))
    if (this%model%fracture) then
      allocate(this%h_frag(history_chunk), this%h_largest(n_largest, history_chunk))
      call this%events%init()
    end if
    ! the sample: probes, spring probes, and the failures this rank found (fracture)
    allocate(this%sample(4 + 4*np + 2*springs_per_cell*nsp + merge(1, 0, this%model%fracture)))
    ! the set-up's wall time and the peak memory so far (largest over ranks), for benchmarks
    peak = real(peak_rss_bytes(), wp)/1048576.0_wp
    call MPI_Allreduce(MPI_IN_PLACE, peak, 1, mpi_wp(), MPI_MAX, comm)
    k = nint(100.0_wp*(MPI_Wtime() - wall_setup))
    write(line, '(a,i0,a,i2.2,a,f0.1,a)') 'set-up: ', k/100, '.', mod(k, 100), ' s, peak ', &
      peak(1), ' MB per rank (largest)'
    call log_info(trim(line))
    stat = 0
    msg = ''
  end procedure simulation_setup

  !> The reaction series: one a &bc name, several &bc of one name sharing it (an unnamed
  !> &bc, or one whose name cannot name a dataset, is bc_<k>, k its 1-based index).
  subroutine reaction_series(this)
    type(simulation_t), intent(inout) :: this
    character(len=64) :: name
    character(len=64), allocatable :: names(:)
    integer :: b, s, ns
    allocate(names(size(this%cfg%bcs)), this%series_bcs(size(this%cfg%bcs)), &
             this%bc_series(size(this%cfg%bcs)))
    ns = 0
    do b = 1, size(this%cfg%bcs)
      name = this%cfg%bcs(b)%name
      if (len_trim(name) == 0 .or. index(name, '/') > 0 .or. name == '.') name = 'bc_'//itoa(b)
      s = findloc(names(1:ns), name, 1)
      if (s == 0) then
        ns = ns + 1
        s = ns
        names(s) = name
        this%series_bcs(s) = itoa(b)
      else
        this%series_bcs(s) = trim(this%series_bcs(s))//' '//itoa(b)
      end if
      this%bc_series(b) = s
    end do
    this%series_names = names(1:ns)
    this%series_bcs = this%series_bcs(1:ns)
  end subroutine reaction_series

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
    mc%nonlinear = any(this%cfg%materials(:)%nonlinear)
    mc%depth = maxval(this%cfg%materials(:)%history_depth)
    mc%fracture = any(this%cfg%materials(:)%fracture) .or. any(this%cfg%shapes(:)%crack)
    mc%mass_damping = this%cfg%damping%alpha > 0.0_wp
    mc%stiffness_damping = this%cfg%damping%beta > 0.0_wp .or. this%cfg%damping%kind == 'capped'
    need = memory_estimate(mc)
    call memory_check(this%comm, need, label, stat, msg, info)
    if (stat == 0) call log_info(info)
  end subroutine check_memory

  !> Log the partition's balance and halo: owned nodes of the largest rank against the mean,
  !> and the halo nodes of all ranks (what the exchange carries each time). Collective.
  subroutine report_partition(this)
    type(simulation_t), intent(in) :: this
    integer(i8) :: v(3)
    character(len=8) :: imbalance, share
    if (this%n_ranks == 1) return
    v = [int(this%lat%n_owned, i8), int(this%lat%n_local - this%lat%n_owned, i8), 0_i8]
    v(3) = v(1)
    call MPI_Allreduce(MPI_IN_PLACE, v(1:2), 2, MPI_INTEGER8, MPI_SUM, this%comm)
    call MPI_Allreduce(MPI_IN_PLACE, v(3:3), 1, MPI_INTEGER8, MPI_MAX, this%comm)
    write(imbalance, '(f8.3)') real(v(3), wp)*this%n_ranks/real(v(1), wp)
    write(share, '(f8.1)') 100.0_wp*real(v(2), wp)/real(v(1), wp)
    call log_info('partition: '//itoa(this%n_ranks)//' ranks, largest/mean owned nodes '// &
                  trim(adjustl(imbalance))//', halo nodes '//itoa(v(2))//' ('// &
                  trim(adjustl(share))//'% of the nodes)')
  end subroutine report_partition

  !> Log a body in several pieces ('warn': a warning; 'allow': an info line) or refuse it
  !> ('one': stat = 1, msg).
  subroutine report_pieces(this, stat, msg)
    type(simulation_t), intent(in) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: text
    integer :: k
    stat = 0
    msg = ''
    if (this%body%n_pieces <= 1) return
    text = 'the body is in '//itoa(this%body%n_pieces)//' pieces (cells joined through '// &
           'shared nodes); a cell of each but the largest:'
    do k = 1, this%body%n_listed
      text = text//' ('//rtoa(this%body%piece_xy(1, k))//', '// &
             rtoa(this%body%piece_xy(2, k))//')'
    end do
    select case (trim(this%cfg%geometry%pieces))
    case ('one')
      stat = 1
      msg = trim(this%cfg%input_file)//": &geometry: pieces = 'one': "//text
    case ('allow')
      call log_info(text)
    case default
      call log_warn(text//"; a piece without supports floats free (pieces = 'allow' "// &
                    "accepts this silently, 'one' refuses it)")
    end select
  end subroutine report_pieces

  !> Documented at its interface in iem_simulation.f90: called once the mesh output's
  !> temporaries are gone, so that they do not add to the peak memory.
  module procedure allocate_state
    type(alloc_guard_t) :: guard
    logical :: work
    work = .false.
    if (.not. this%static) work = this%integ%work_arrays()
    call this%st%init(this%lat%n_owned, this%lat%n_local, this%model%n_state, &
                      rk4_work=work, guard=guard, n_rates=this%model%rate_columns(this%lat, work))
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    if (.not. this%static) call initial_velocity(this)
    call this%model%prescribe(this%st%y, 0.0_wp)
  end procedure allocate_state

  !> Documented at its interface in iem_simulation.f90.
  module procedure initial_velocity
    integer :: l
    real(wp) :: xy(2)
    associate(ini => this%cfg%initial)
      do l = 1, this%lat%n_owned
        xy = this%lat%node_xy(l) - ini%center
        this%st%y(3:4, l) = ini%velocity + ini%angular_velocity*[-xy(2), xy(1)]
        if (this%model%n_state == 6) this%st%y(5:6, l) = this%st%y(3:4, l)
      end do
    end associate
  end procedure initial_velocity

end submodule iem_simulation_setup
