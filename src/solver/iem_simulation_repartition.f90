!> Repartitioning during a run: the state of every node and the history of every cell are
!> registered as fields (state_to_registry: the one list the checkpoint uses too), the
!> weighted bisection recomputes the partition (with new node weights), the fields move with
!> their nodes and cells (iem_migration), and what derives from the lattice
!> (the model's supports, loads and masses, the probes' places, the output's selections) is
!> rebuilt from it; load balancing (balance_run) repartitions so with the ranks' parts in
!> proportion to their measured speeds. The trajectory and the history are bitwise those of
!> a run that is not repartitioned (forces are summed per node in cell order, energies are
!> exact sums).
submodule (iem_simulation) iem_simulation_repartition
  use iem_migration, only: repartition
  use iem_exact_sum, only: exact_sum_t, exact_sum_allreduce
  use iem_kinds, only: ip
  use iem_timers, only: timer_total, t_force, t_update
  use mpi_f08, only: MPI_SUM, MPI_Allgather, MPI_DOUBLE_PRECISION
  implicit none

  !> The x below which left_heavy weighs a node 10 (set by repartition_run before it
  !> repartitions; a module procedure, not an internal one, needs no trampoline).
  real(wp) :: heavy_below_x = 0.0_wp

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure repartition_run
    type(field_registry_t), target :: reg
    integer(i8), allocatable :: old_owned(:), n_selected(:)
    type(exact_sum_t) :: w_ext, w_damp, en, kd(1)
    type(alloc_guard_t) :: guard
    integer :: ns, l, k2, moved(1), ierr

    ns = this%model%n_state
    ! the kicks' term (velocity Verlet) of the last evaluation, on the lattice it was made on,
    ! for a sample at this step (the rebuilt model's damping powers are not that
    ! evaluation's)
    kd = [this%model%kick_term(this%lat, this%st%acc, this%integ%kick_half(this%dt))]
    call exact_sum_allreduce(kd, this%comm)
    this%kick = kd(1)%value()
    this%kick_step = k
    ! register the run's per-node and per-cell state and copy it in (all of it, also what a
    ! checkpoint leaves out)
    call state_to_registry(this, reg, .false., stat)
    if (stat /= 0) then
      msg = 'repartition at step '//itoa(k)//': registering the fields failed'
      return
    end if
    old_owned = this%lat%owned_gids()

    ! the new partition: with share, the body's own bisection with the ranks' parts in
    ! proportion to it; else the bisection with the nodes of the left half of the grid ten
    ! times heavier than the rest, so that many nodes change rank
    if (present(share)) then
      call repartition(this%body, this%comm, this%lat, this%halo, reg, stat, msg, width=ns, &
                       share=share)
    else
      heavy_below_x = 0.5_wp*this%grid%nx*this%grid%lx
      call repartition(this%body, this%comm, this%lat, this%halo, reg, stat, msg, &
                       weight=left_heavy, width=ns)
    end if
    if (stat /= 0) then
      msg = 'repartition at step '//itoa(k)//': '//msg
      return
    end if

    ! rebuild what derives from the lattice; the work done so far and the strain energy of
    ! the last evaluation stay with the ranks (exact sums: their global sums are unchanged)
    w_ext = this%model%w_ext_acc
    w_damp = this%model%w_damp_acc
    en = this%model%en_sum
    allocate(n_selected(size(this%cfg%bcs) + size(this%cfg%loads)))
    this%model = model_t()
    call this%model%init(this%cfg, this%body, this%lat, n_selected, guard)
    if (.not. guard%failed) call this%st%init(this%lat%n_owned, this%lat%n_local, ns, &
                                               rk4_work=this%integ%work_arrays(), guard=guard, &
                                               n_rates=this%model%rate_columns(this%lat, &
                                                 this%integ%work_arrays()))
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    this%model%w_ext_acc = w_ext
    this%model%w_damp_acc = w_damp
    this%model%en_sum = en
    ! copy the fields back into the new model and state (the prescribed velocities with them,
    ! as the step before set them: prescribing them again at k dt, not that step's t + dt,
    ! could move them by a rounding of t)
    call state_from_registry(this, reg)
    ! the halo columns of y are refreshed by the next force evaluation's exchange; Verlet's
    ! step uses only owned values before it
    do k2 = 1, size(this%probe_gid)
      this%probe_local(k2) = this%lat%local_of(this%probe_gid(k2))
    end do
    do k2 = 1, size(this%sp_cell)
      this%sp_local(k2) = 0
      do l = 1, this%lat%n_cells
        if (this%lat%cell_gid(l) == this%sp_cell(k2) .and. this%lat%cell_counted(l)) &
          this%sp_local(k2) = l
      end do
    end do
    if (allocated(this%cell_degree)) then
      deallocate(this%cell_degree)
      allocate(this%cell_degree(this%lat%n_counted()), stat=ierr)
      if (ierr /= 0) then
        stat = 1
        msg = 'repartition at step '//itoa(k)//': out of memory'
        return
      end if
    end if
    call this%out%set_owned(this%lat%owned_gids(), counted_cell_gids(this), &
                            stat, msg)
    if (stat /= 0) return
    ! nodes that came from another rank (both lists ascending)
    moved = 0
    l = 1
    do k2 = 1, this%lat%n_owned
      do while (l <= size(old_owned))
        if (old_owned(l) >= this%lat%node_gid(k2)) exit
        l = l + 1
      end do
      if (l > size(old_owned)) then
        moved = moved + 1
      else if (old_owned(l) /= this%lat%node_gid(k2)) then
        moved = moved + 1
      end if
    end do
    call MPI_Allreduce(MPI_IN_PLACE, moved, 1, MPI_INTEGER, MPI_SUM, this%comm)
    if (present(share)) then
      call log_info('balanced at step '//itoa(k)//' (parts in proportion to the ranks'' '// &
                    'speeds): '//itoa(moved(1))//' of '//itoa(this%body%n_nodes)// &
                    ' nodes changed rank')
    else
      call log_info('repartitioned at step '//itoa(k)//' (bisection with new node weights): '// &
                    itoa(moved(1))//' of '//itoa(this%body%n_nodes)//' nodes changed rank')
    end if
    call reg%free()

  end procedure repartition_run

  !> Documented at its interface in iem_simulation.f90.
  module procedure balance_run
    real(wp) :: mine(2), mean_time, mean_share
    real(wp), allocatable :: all(:, :), share(:)
    real(wp) :: now

    stat = 0
    msg = ''
    ! this rank's computing since the last look (waits for other ranks count as halo
    ! exchange, not here) and its owned nodes; every rank gets every rank's
    now = timer_total(t_force) + timer_total(t_update)
    mine = [now - this%balance_mark, real(this%lat%n_owned, wp)]
    this%balance_mark = now
    allocate(all(2, 0:this%n_ranks - 1), share(0:this%n_ranks - 1))
    call MPI_Allgather(mine, 2, MPI_DOUBLE_PRECISION, all, 2, MPI_DOUBLE_PRECISION, this%comm)
    mean_time = sum(all(1, :))/real(this%n_ranks, wp)
    if (.not. (maxval(all(1, :)) > (1.0_wp + this%cfg%run%balance_tolerance)*mean_time)) return
    if (any(.not. (all(1, :) > 0.0_wp))) return
    ! each rank's speed (nodes per second of computing): its share of the new partition,
    ! kept within half and twice the mean, so that a burst of noise cannot starve a rank
    share = all(2, :)/all(1, :)
    mean_share = sum(share)/real(this%n_ranks, wp)
    share = min(max(share, 0.5_wp*mean_share), 2.0_wp*mean_share)
    call repartition_run(this, k, stat, msg, share)
    ! the new partition's time starts now
    this%balance_mark = timer_total(t_force) + timer_total(t_update)
  end procedure balance_run

  !> Weight of a node in the new partition: 10 left of heavy_below_x, else 1.
  pure integer(i8) function left_heavy(x, y)
    real(wp), intent(in) :: x, y
    left_heavy = merge(10_i8, 1_i8, x < heavy_below_x .and. y > -1.0_wp)
  end function left_heavy
end submodule iem_simulation_repartition
