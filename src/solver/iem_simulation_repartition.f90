!> Repartitioning during a run: the state of every node and the history of every cell are
!> registered once as fields, the weighted bisection recomputes the partition (with new node
!> weights), the fields move with their nodes and cells (iem_migration), and what derives from the lattice
!> (the model's supports, loads and masses, the probes' places, the output's selections) is
!> rebuilt from it. The trajectory and the history are bitwise those of a run that is not
!> repartitioned (forces are summed per node in cell order, energies are exact sums).
submodule (iem_simulation) iem_simulation_repartition
  use iem_fields, only: field_registry_t, centre_node, centre_cell, kind_real, kind_int
  use iem_migration, only: repartition
  use iem_exact_sum, only: exact_sum_t
  use iem_nonlinear_springs, only: springs_per_cell
  use iem_kinds, only: ip
  use mpi_f08, only: MPI_SUM
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure repartition_run
    type(field_registry_t), target :: reg
    integer(i8), allocatable :: old_owned(:), n_selected(:)
    type(exact_sum_t) :: w_ext, w_damp
    type(alloc_guard_t) :: guard
    integer :: id_y, id_acc, id_snap, id_en, ids(9), ns, depth, l, k2, moved(1), ierr
    real(wp), pointer :: r2(:, :)
    integer(ip), pointer :: i2(:, :)
    logical :: nl, snap

    ns = this%model%n_state
    nl = this%model%nonlinear
    snap = allocated(this%snap)
    if (snap) snap = size(this%snap, 2) > 0
    ! register the run's per-node and per-cell state and copy it in
    call reg%init(this%lat%n_local, this%lat%n_cells)
    call reg%add('y', centre_node, kind_real, ns, id_y, stat)
    if (stat == 0) call reg%add('acc', centre_node, kind_real, ns - 2, id_acc, stat)
    id_snap = 0
    if (stat == 0 .and. snap) call reg%add('last_good', centre_node, kind_real, 4, id_snap, stat)
    if (stat == 0) call reg%add('cell_energy', centre_cell, kind_real, 1, id_en, stat)
    ids = 0
    if (nl .and. stat == 0) then
      depth = int(this%model%nl%state%depth)
      call add_cell('strain', kind_real, springs_per_cell, ids(1))
      call add_cell('stress', kind_real, springs_per_cell, ids(2))
      call add_cell('e_max_pos', kind_real, springs_per_cell, ids(3))
      call add_cell('e_max_neg', kind_real, springs_per_cell, ids(4))
      call add_cell('work', kind_real, springs_per_cell, ids(5))
      call add_cell('dir', kind_int, springs_per_cell, ids(6))
      call add_cell('count', kind_int, springs_per_cell, ids(7))
      call add_cell('e_rev', kind_real, springs_per_cell*depth, ids(8))
      call add_cell('s_rev', kind_real, springs_per_cell*depth, ids(9))
    end if
    if (stat /= 0) then
      msg = 'repartition at step '//itoa(k)//': registering the fields failed'
      return
    end if
    r2 => reg%real_data(id_y)
    r2 = this%st%y
    r2 => reg%real_data(id_acc)
    r2(:, 1:this%lat%n_owned) = this%st%acc
    if (id_snap > 0) then
      r2 => reg%real_data(id_snap)
      r2(:, 1:this%lat%n_owned) = this%snap
    end if
    r2 => reg%real_data(id_en)
    r2(1, :) = this%model%en_cell
    if (nl) call springs_to(reg)
    old_owned = this%lat%gid(1:this%lat%n_owned)

    ! the new partition: the bisection with the nodes of the left half of the grid ten times
    ! heavier than the rest, so that many nodes change rank (the costs that load balancing
    ! will measure take this place later)
    call repartition(this%body, this%comm, this%lat, this%halo, reg, stat, msg, &
                     weight=left_heavy, width=ns)
    if (stat /= 0) then
      msg = 'repartition at step '//itoa(k)//': '//msg
      return
    end if

    ! rebuild what derives from the lattice; the work done so far stays with the ranks
    w_ext = this%model%w_ext_acc
    w_damp = this%model%w_damp_acc
    allocate(n_selected(size(this%cfg%bcs) + size(this%cfg%loads)))
    this%model = model_t()
    call this%model%init(this%cfg, this%body, this%lat, n_selected, guard)
    if (.not. guard%failed) call this%st%init(this%lat%n_owned, this%lat%n_local, ns, &
                                               rk4_work=this%integ%work_arrays(), guard=guard)
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    this%model%w_ext_acc = w_ext
    this%model%w_damp_acc = w_damp
    r2 => reg%real_data(id_y)
    this%st%y = r2
    r2 => reg%real_data(id_acc)
    this%st%acc = r2(:, 1:this%lat%n_owned)
    if (id_snap > 0) then
      deallocate(this%snap)
      r2 => reg%real_data(id_snap)
      this%snap = r2(:, 1:this%lat%n_owned)
    end if
    r2 => reg%real_data(id_en)
    this%model%en_cell = r2(1, :)
    if (nl) call springs_from(reg)
    call this%model%prescribe(this%st%y, real(k, wp)*this%dt)
    ! the halo columns of y are refreshed by the next force evaluation's exchange; Verlet's
    ! step uses only owned values before it
    do k2 = 1, size(this%probe_gid)
      this%probe_local(k2) = findloc(this%lat%gid(1:this%lat%n_owned), this%probe_gid(k2), 1)
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
    call this%out%set_owned(this%lat%gid(1:this%lat%n_owned), counted_cell_gids(this), &
                            stat, msg)
    if (stat /= 0) return
    ! nodes that came from another rank (both lists ascending)
    moved = 0
    l = 1
    do k2 = 1, this%lat%n_owned
      do while (l <= size(old_owned))
        if (old_owned(l) >= this%lat%gid(k2)) exit
        l = l + 1
      end do
      if (l > size(old_owned)) then
        moved = moved + 1
      else if (old_owned(l) /= this%lat%gid(k2)) then
        moved = moved + 1
      end if
    end do
    call MPI_Allreduce(MPI_IN_PLACE, moved, 1, MPI_INTEGER, MPI_SUM, this%comm)
    call log_info('repartitioned at step '//itoa(k)//' (bisection with new node weights): '// &
                  itoa(moved(1))//' of '//itoa(this%body%n_nodes)//' nodes changed rank')
    call reg%free()

  contains

    !> Weight of a node in the new partition: 10 in the left half of the grid, else 1.
    pure integer(i8) function left_heavy(x, y)
      real(wp), intent(in) :: x, y
      left_heavy = merge(10_i8, 1_i8, x < 0.5_wp*this%grid%nx*this%grid%lx .and. y > -1.0_wp)
    end function left_heavy

    subroutine add_cell(name, kind, width, id)
      character(len=*), intent(in) :: name
      integer, intent(in) :: kind, width
      integer, intent(out) :: id
      if (stat == 0) call reg%add(name, centre_cell, kind, width, id, stat)
    end subroutine add_cell

    !> Copy the springs' history into the registry (12 springs a cell, in cell order).
    subroutine springs_to(r)
      type(field_registry_t), intent(inout), target :: r
      associate(st => this%model%nl%state)
        r2 => r%real_data(ids(1))
        r2 = reshape(st%strain, shape(r2))
        r2 => r%real_data(ids(2))
        r2 = reshape(st%stress, shape(r2))
        r2 => r%real_data(ids(3))
        r2 = reshape(st%e_max_pos, shape(r2))
        r2 => r%real_data(ids(4))
        r2 = reshape(st%e_max_neg, shape(r2))
        r2 => r%real_data(ids(5))
        r2 = reshape(this%model%nl%work, shape(r2))
        i2 => r%int_data(ids(6))
        i2 = reshape(st%dir, shape(i2))
        i2 => r%int_data(ids(7))
        i2 = reshape(st%count, shape(i2))
        r2 => r%real_data(ids(8))
        r2 = reshape(st%e_rev, shape(r2))
        r2 => r%real_data(ids(9))
        r2 = reshape(st%s_rev, shape(r2))
      end associate
    end subroutine springs_to

    !> Copy the springs' history back from the registry into the model's new springs.
    subroutine springs_from(r)
      type(field_registry_t), intent(inout), target :: r
      associate(st => this%model%nl%state)
        r2 => r%real_data(ids(1))
        st%strain = reshape(r2, shape(st%strain))
        r2 => r%real_data(ids(2))
        st%stress = reshape(r2, shape(st%stress))
        r2 => r%real_data(ids(3))
        st%e_max_pos = reshape(r2, shape(st%e_max_pos))
        r2 => r%real_data(ids(4))
        st%e_max_neg = reshape(r2, shape(st%e_max_neg))
        r2 => r%real_data(ids(5))
        this%model%nl%work = reshape(r2, shape(this%model%nl%work))
        i2 => r%int_data(ids(6))
        st%dir = reshape(i2, shape(st%dir))
        i2 => r%int_data(ids(7))
        st%count = reshape(i2, shape(st%count))
        r2 => r%real_data(ids(8))
        st%e_rev = reshape(r2, shape(st%e_rev))
        r2 => r%real_data(ids(9))
        st%s_rev = reshape(r2, shape(st%s_rev))
      end associate
    end subroutine springs_from
  end procedure repartition_run
end submodule iem_simulation_repartition
