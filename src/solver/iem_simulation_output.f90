!> Output recording of a run: the output file's creation, history samples (energies,
!> probes, spring probes, reactions, fracture events and fragments) gathered into the
!> buffer and flushed to the file, and frames.
submodule (iem_simulation) iem_simulation_output
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_SUM
  use iem_kinds, only: mpi_wp
  use iem_relaxation, only: relax_check_interval
  use iem_cell_kernel, only: cell_strain_measures
  use iem_nonlinear_springs, only: springs_per_cell, spring_kind, spring_strains
  use iem_build_info, only: iem_version
  use iem_exact_sum, only: exact_sum_allreduce
  use iem_lattice_queries, only: node_place
  use iem_cell_table, only: max_chunk
  use iem_fracture, only: edge_factor, shear_factor, failure_kind, intact_time
  implicit none

contains

  !> Create the output file, or reopen that of the interrupted run when continuing one.
  module procedure open_output
    if (this%restart%step > 0) then
      call reopen_output(this, stat, msg)
      if (stat == 0) call this%out%reopen_series(this%series_names, this%model%fracture, &
        this%restart%n_samples, this%restart%last_sample(1), stat, msg)
    else
      call create_output(this, stat, msg)
    end if
  end procedure open_output

  !> Global indices of this rank's counted cells, ascending.
  module procedure counted_cell_gids
    integer :: l, k
    allocate(g(this%lat%n_counted()))
    k = 0
    do l = 1, this%lat%n_cells
      if (.not. this%lat%cell_counted(l)) cycle
      k = k + 1
      g(k) = this%lat%cell_gid(l)
    end do
  end procedure counted_cell_gids

  !> Create the output file and write the mesh, the spring probes and the static settings.
  subroutine create_output(this, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=64), allocatable :: names(:), sp_names(:)
    real(wp), allocatable :: pxy(:, :), nxy(:, :), sp_xy(:, :)
    integer(i8), allocatable :: cells(:, :), cell_gids(:), material(:)
    real(wp), allocatable :: coords(:, :)
    character(len=:), allocatable :: material_names
    integer :: k, l, nc, ierr, q, r, l0, l1, i0, j, jc, i, m, cq(4, max_chunk)
    integer(i8) :: nodes(4), g0
    type(alloc_guard_t) :: guard

    associate(p => this%cfg%probes)
      allocate(names(size(p)), pxy(2, size(p)), nxy(2, size(p)))
      do k = 1, size(p)
        names(k) = p(k)%name
        pxy(:, k) = [p(k)%x, p(k)%y]
        nxy(:, k) = node_place(this%lat, this%comm, this%probe_gid(k))
      end do
    end associate
    call this%out%create(trim(this%cfg%run%output_file), this%comm, this%cfg%run%overwrite, &
      iem_version, trim(this%cfg%input_file), this%cfg%input_text, trim(this%cfg%run%analysis), &
      this%body%n_nodes, this%body%n_cells, this%lat%owned_gids(), names, pxy, &
      this%probe_gid, nxy, stat, msg)
    if (stat /= 0) return
    this%output_open = .true.
    ! the coordinates first, freed before the cells' buffers are made (they do not add up)
    allocate(coords(2, this%lat%n_owned), stat=ierr)
    call guard%note(ierr, 'the mesh output buffers', 16.0_wp*this%lat%n_owned)
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    do r = 1, this%lat%node_runs%n
      call this%lat%owned_run(r, l0, l1, i0, j, g0)
      do l = l0, l1
        coords(:, l) = [(i0 + l - l0)*this%lat%lx, j*this%lat%ly]
      end do
    end do
    call this%out%write_mesh_coordinates(coords, stat, msg)
    if (stat /= 0) return
    deallocate(coords)
    nc = this%lat%n_counted()
    allocate(cells(4, nc), cell_gids(nc), material(nc), stat=ierr)
    call guard%note(ierr, 'the mesh output buffers', 48.0_wp*nc)
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    ! the counted cells chunk by chunk (their corners without a lookup a cell)
    k = 0
    do jc = 1, this%lat%cells%n_chunks()
      call this%lat%cells%chunk_corners(jc, cq, m)
      do i = 1, m
        if (cq(1, i) > this%lat%n_owned) cycle
        l = this%lat%cells%chunks(1, jc) + i - 1
        k = k + 1
        nodes = [(this%lat%node_gid(cq(q, i)), q = 1, 4)]
        cells(:, k) = nodes
        cell_gids(k) = this%lat%cell_gid(l)
        material(k) = this%lat%mat(l)
      end do
    end do
    material_names = ''
    do k = 1, size(this%cfg%materials)
      if (k > 1) material_names = material_names//','
      if (len_trim(this%cfg%materials(k)%name) == 0) then
        material_names = material_names//'default'
      else
        material_names = material_names//trim(this%cfg%materials(k)%name)
      end if
    end do
    call this%out%write_mesh(mass=this%model%mass, cells=cells, cell_gids=cell_gids, &
      nx=this%grid%nx, ny=this%grid%ny, lx=this%grid%lx, ly=this%grid%ly, &
      thickness=this%grid%thickness, plane=trim(this%cfg%geometry%plane), stat=stat, msg=msg, &
      material=material, material_names=material_names)
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
    call this%out%define_reactions(this%series_names, this%series_bcs, stat, msg)
    if (stat /= 0) return
    if (this%model%fracture) then
      call this%out%define_fracture_history(stat, msg)
      if (stat /= 0) return
    end if
    if (.not. this%static) return
    associate(s => this%cfg%static)
      call this%out%write_static_settings(s%load_steps, s%tolerance, s%max_iterations, &
        trim(s%method), trim(s%mass), relax_check_interval, stat, msg)
    end associate
  end subroutine create_output

  !> Gather one history sample (global sums with one Allreduce) into the buffer.
  module procedure record_sample
    integer :: p, np, b, stat, o, n_failed
    real(wp) :: ke, se, e, e_bal, kick, scale, frac, t_from

    np = size(this%probe_gid)
    this%sample = 0.0_wp
    ! the energies are exact sums (below); a static run's work is its load steps' (summed here)
    if (this%static) this%sample(3:4) = [this%w_ext, this%w_damp]
    do p = 1, np
      if (this%probe_local(p) > 0) then
        this%sample(4 + 4*(p - 1) + 1:4 + 4*p) = this%st%y(1:4, this%probe_local(p))
      end if
    end do
    o = 4 + 4*np
    do p = 1, size(this%sp_probe)
      if (this%sp_local(p) > 0) call spring_sample(this, p, this%sp_local(p), &
        this%sample(o + 1:o + springs_per_cell), &
        this%sample(o + springs_per_cell + 1:o + 2*springs_per_cell))
      o = o + 2*springs_per_cell
    end do
    ! fracture: the failures this rank counts since the last sample (the first: from t = 0 on,
    ! so with the pre-cut springs); their number over the ranks comes with the sample's sum
    if (this%model%fracture) then
      t_from = this%last_sample(1)
      if (k == 0) t_from = -1.0_wp
      call this%events%collect(this%lat, this%model%fr, t_from, t)
      this%sample(size(this%sample)) = real(this%events%n_loc, wp)
    end if
    call MPI_Allreduce(MPI_IN_PLACE, this%sample, size(this%sample), mpi_wp(), MPI_SUM, this%comm)
    ! the energies and the reactions as exact sums over nodes, cells and evaluations: the
    ! same bits on any number of ranks and partition (a static run's work comes from its load
    ! steps)
    if (this%static) then
      call this%model%energy_sums(this%lat, this%st%y, this%xsums(1:6))
    else
      call this%model%energy_sums(this%lat, this%st%y, this%xsums(1:6), this%st%acc, &
                                  this%integ%kick_half(this%dt))
    end if
    do p = 7, size(this%xsums)
      call this%xsums(p)%reset()
    end do
    call this%model%reaction_sums(this%st%y, t, this%bc_series, .not. this%static, &
                                  this%xsums(7:))
    call exact_sum_allreduce(this%xsums, this%comm)
    this%sample(1) = this%xsums(1)%value()
    this%sample(2) = this%xsums(2)%value()
    if (.not. this%static) then
      this%sample(3) = this%xsums(3)%value()
      this%sample(4) = this%xsums(4)%value()
    end if
    frac = this%xsums(5)%value()
    diverged = .not. all(ieee_is_finite(this%sample))
    if (diverged) return
    if (this%n_buf == size(this%h_time)) call flush_history(this, stat)
    b = this%n_buf + 1
    this%n_buf = b
    ke = this%sample(1)
    se = this%sample(2)
    e = ke + se
    ! the energy the steps' work balances: with kicks (velocity Verlet) the kinetic energy of
    ! the velocities of the half steps around this state, ke less the kicks' term; at the
    ! step of a checkpoint or a repartitioning, that term as the step's own evaluation gave it
    ! (the evaluation since took the state's velocities for the damping, not the half step's)
    kick = this%xsums(6)%value()
    if (k == this%kick_step) kick = this%kick
    e_bal = (ke - kick) + se
    if (k == 0) then
      this%e0 = e_bal
      this%e_scale = 0.0_wp
    end if
    ! scale: the largest energy the run has held so far, so that the error stays meaningful
    ! when the current energy passes through zero
    this%e_scale = max(this%e_scale, abs(this%sample(3)), e, this%sample(4), frac)
    scale = max(this%e_scale, tiny(1.0_wp))
    this%last_balance = abs(e_bal + this%sample(4) + frac - this%sample(3) - this%e0)/scale
    if (k == 0) this%last_balance = 0.0_wp
    this%h_time(b) = t
    this%h_step(b) = k
    this%h_energy(:, b) = [ke, se, this%sample(3), this%sample(4), frac, this%last_balance]
    this%last_sample(1) = t
    this%last_sample(2:7) = this%h_energy(:, b)
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
    do p = 1, size(this%series_names)
      this%h_react(:, p, b) = [this%xsums(5 + 2*p)%value(), this%xsums(6 + 2*p)%value()]
    end do
    if (.not. this%model%fracture) return
    ! the failures to rank 0, in canonical order; the fragments counted again only when
    ! springs failed since the last count (or none was made since the run (re)started)
    n_failed = nint(this%sample(size(this%sample)))
    call this%events%gather(this%comm, n_failed)
    if (n_failed > 0 .or. .not. this%frag_valid) then
      ! made for the history's fragment series alone: output's time
      call timer_start(t_output)
      call this%frag%count(this%lat, this%halo, this%comm, this%model%fr, this%n_frag, &
                           this%frag_sizes)
      call timer_stop(t_output)
      this%frag_valid = .true.
    end if
    this%h_frag(b) = this%n_frag
    this%h_largest(:, b) = this%frag_sizes
  end procedure record_sample

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

  !> Strains and stresses of the 12 springs of local cell c (that of spring probe p) at the
  !> current state (committed: samples are taken at accepted states).
  subroutine spring_sample(this, p, c, strain, stress)
    type(simulation_t), intent(in) :: this
    integer, intent(in) :: p, c
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
        stress(j) = this%moduli(spring_kind(j), p)* &
                    this%model%nl%state%stress(springs_per_cell*(c - 1) + j)
      else
        stress(j) = this%moduli(spring_kind(j), p)*strain(j)
      end if
    end do
  end subroutine spring_sample

  !> Write the buffered history samples to the file.
  module procedure flush_history
    character(len=:), allocatable :: msg
    integer :: n
    stat = 0
    n = this%n_buf
    if (n == 0 .or. .not. this%output_open) return
    ! the other series first: the energies' write ends with the file's flush, so that a
    ! checkpoint written next finds every series on disk as long as the energies
    if (size(this%sp_probe) > 0) call this%out%write_spring_history(n, &
      this%h_sp_e(:, :, 1:n), this%h_sp_s(:, :, 1:n), stat, msg)
    if (stat == 0) then
      if (this%model%fracture) then
        call this%out%write_series(n, this%h_react(:, :, 1:n), stat, msg, &
          fragments=this%h_frag(1:n), largest=this%h_largest(:, 1:n))
        associate(ev => this%events)
          if (stat == 0) call this%out%write_events(ev%n_buf, ev%time, ev%x, ev%y, ev%kind, &
            ev%cell, ev%spring, stat, msg)
        end associate
        call this%events%clear()
      else
        call this%out%write_series(n, this%h_react(:, :, 1:n), stat, msg)
      end if
    end if
    if (stat == 0) then
      if (this%static) then
        call this%out%write_history(n, this%h_time(1:n), this%h_step(1:n), &
          this%h_energy(:, 1:n), this%h_pu(:, :, 1:n), this%h_pv(:, :, 1:n), stat, msg, &
          load_factor=this%h_load(1:n), iterations=this%h_iter(1:n), residual=this%h_res(1:n))
      else
        call this%out%write_history(n, this%h_time(1:n), this%h_step(1:n), &
          this%h_energy(:, 1:n), this%h_pu(:, :, 1:n), this%h_pv(:, :, 1:n), stat, msg)
      end if
    end if
    this%n_buf = 0
  end procedure flush_history

  !> Documented at its interface in iem_simulation.f90.
  module procedure crossed
    crossed = floor(t/interval*(1.0_wp + 1.0e-12_wp)) > floor(t_prev/interval*(1.0_wp + 1.0e-12_wp))
    if (t_prev < 0.0_wp) crossed = .true.
  end procedure crossed

  !> Write a frame of the state at step k (and the cells' degree of nonlinearity, or their
  !> damage and failed springs).
  module procedure write_frame
    character(len=:), allocatable :: msg
    integer :: n
    n = this%lat%n_owned
    ! rows 1:2 (u) and 3:4 (v) of the owned columns: the writer copies one field at a time
    call this%out%write_frame(k, t, this%st%y(:, 1:n), this%st%y(:, 1:n), stat, msg, u_row=1, &
                              v_row=3)
    this%last_frame_time = t
    if (stat /= 0) return
    if (this%model%nonlinear) then
      call nonlinearity_degree(this)
      call this%out%write_cell_field('nonlinearity', this%cell_degree, stat, msg)
      if (stat /= 0) return
    end if
    if (this%model%fracture) call write_fracture_fields(this, stat)
  end procedure write_frame

  !> The fracture fields of the frame just written, from the committed fracture state: each
  !> counted cell's damage (1 - the mean of its 8 effective intact factors: edges fe_q, shear
  !> springs min(fs_q, fe_q, fe_q-1)) and the springs of the counted cells that failed by
  !> their own criterion or were pre-cut (global cell, spring 0-7, how, when). Buffers are
  !> made here, at output time: the list's length is that of the failed springs.
  subroutine write_fracture_fields(this, stat)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable :: msg
    real(wp), allocatable :: damage(:), when(:)
    integer(i8), allocatable :: cell(:)
    integer, allocatable :: spring(:), how(:)
    real(wp) :: fe(4), fs(4), s
    integer :: c, q, j, k, m, mt, nf

    associate(fr => this%model%fr, lat => this%lat)
      nf = 0
      do c = 1, lat%n_cells
        if (lat%cell_counted(c)) nf = nf + count(fr%t_fail(:, c) /= intact_time)
      end do
      allocate(damage(lat%n_counted()), cell(nf), spring(nf), how(nf), when(nf))
      k = 0
      m = 0
      mt = 1
      do c = 1, lat%n_cells
        if (.not. lat%cell_counted(c)) cycle
        k = k + 1
        if (this%model%mixed) mt = lat%mat(c)
        do q = 1, 4
          fe(q) = edge_factor(fr%laws(mt), fr%kappa(:, c), q)
          fs(q) = shear_factor(fr%laws(mt), fr%kappa(:, c), q)
        end do
        s = sum(fe)
        do q = 1, 4
          s = s + min(fs(q), fe(q), fe(modulo(q - 2, 4) + 1))
        end do
        damage(k) = 1.0_wp - s/8.0_wp
        do j = 1, 8
          if (fr%t_fail(j, c) == intact_time) cycle
          m = m + 1
          cell(m) = lat%cell_gid(c)
          spring(m) = j - 1
          how(m) = failure_kind(fr%laws(mt), fr%kappa(:, c), j)
          when(m) = fr%t_fail(j, c)
        end do
      end do
    end associate
    call this%out%write_cell_field('damage', damage, stat, msg)
    if (stat /= 0) return
    call this%out%write_failed_springs(cell, spring, how, when, stat, msg)
  end subroutine write_fracture_fields

end submodule iem_simulation_output
