!> The run's per-node and per-cell state as fields of a registry (iem_fields), listed once in
!> each_field below: the checkpoint (iem_restart) and the repartitioning
!> (iem_simulation_repartition) register it, copy it in, move or write the registry's
!> records, and copy it back; a checkpoint's registry borrows the run's arrays instead (no
!> copy: the records are packed from them and read into them). A field added to the list
!> (e.g. the springs' failure flags) is checkpointed (when flagged so) and migrated with no
!> other change.
submodule (iem_simulation) iem_simulation_fields
  use iem_fields, only: centre_node, centre_cell, kind_real, kind_int
  use iem_nonlinear_springs, only: springs_per_cell
  use iem_kinds, only: ip, i8
  implicit none

  !> What each_field does with each field of the list: add it to the registry, copy the
  !> run's array into it, copy it back into the run's array, or add it as the run's array
  !> itself (borrowed; added and copied in where the array does not span the entities).
  integer, parameter :: op_register = 1, op_in = 2, op_out = 3, op_borrow = 4

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure state_to_registry
    logical :: lend
    call reg%init(this%lat%n_local, this%lat%n_cells)
    stat = 0
    lend = .false.
    if (present(borrow)) lend = borrow
    if (lend) then
      call each_field(this, reg, op_borrow, checkpoint, stat)
    else
      call each_field(this, reg, op_register, checkpoint, stat)
      if (stat == 0) call each_field(this, reg, op_in, checkpoint, stat)
    end if
  end procedure state_to_registry

  !> Documented at its interface in iem_simulation.f90.
  module procedure state_from_registry
    integer :: stat
    stat = 0
    call each_field(this, reg, op_out, .false., stat)
    ! the springs' curves are derived from their state
    if (this%model%nonlinear) call this%model%nl%stale()
    if (this%model%fracture) call this%model%fr%refresh(this%lat%cell_mat)
  end procedure state_from_registry

  !> Documented at its interface in iem_simulation.f90.
  module procedure state_layout
    call reg%init(0, 0)
    stat = 0
    call each_field(this, reg, op_register, checkpoint, stat)
  end procedure state_layout

  !> The one list of the run's per-node and per-cell state: for each field its name, centre,
  !> width (values per node or cell), the run's array (entity after entity: a node field's
  !> array has n_local or n_owned columns, a cell field's one value set per local cell, so
  !> the springs' arrays, 12 springs a cell, are cell fields of width 12 or 12*depth) and
  !> whether a checkpoint holds it. op_register adds the fields (only the checkpointed ones
  !> when checkpoint); op_in and op_out copy the fields that reg holds in and out (op_out
  !> leaves a borrowed one, the run's array itself); op_borrow adds them borrowed where it can
  !> (a run's array without values as a field of zeros).
  !> Not a field: the strain energy of the last evaluation, an exact sum of the cells' energies
  !> that the model keeps per rank (model_t's en_sum; the integrator's resume recomputes it).
  subroutine each_field(this, reg, op, checkpoint, stat)
    type(simulation_t), intent(inout), target :: this
    type(field_registry_t), intent(inout), target :: reg
    integer, intent(in) :: op
    logical, intent(in) :: checkpoint
    integer, intent(inout) :: stat
    integer :: ns, depth

    ns = this%model%n_state
    call real_field('y', centre_node, ns, this%st%y, .true.)
    call real_field('acc', centre_node, ns - 2, this%st%acc, .true.)
    call reaction_field()
    if (this%model%alpha > 0.0_wp) &
      call real_field('damping_work', centre_node, 1, this%model%wd_node, .true.)
    if (this%model%beta > 0.0_wp) &
      call real_field('cell_damping_work', centre_cell, 1, this%model%wd_cell, .true.)
    if (this%model%nonlinear) then
      depth = int(this%model%nl%state%depth)
      associate(s => this%model%nl%state)
        call real_field('strain', centre_cell, springs_per_cell, s%strain, .true.)
        call real_field('stress', centre_cell, springs_per_cell, s%stress, .true.)
        call real_field('e_max_pos', centre_cell, springs_per_cell, s%e_max_pos, .true.)
        call real_field('e_max_neg', centre_cell, springs_per_cell, s%e_max_neg, .true.)
        call real_field('work', centre_cell, springs_per_cell, this%model%nl%work, .true.)
        call int_field('dir', centre_cell, springs_per_cell, s%dir, .true.)
        call int_field('count', centre_cell, springs_per_cell, s%count, .true.)
        call real_field('e_rev', centre_cell, springs_per_cell*depth, s%e_rev, .true.)
        call real_field('s_rev', centre_cell, springs_per_cell*depth, s%s_rev, .true.)
      end associate
    end if
    if (this%model%fracture) then
      call real_field('fracture_kappa', centre_cell, 12, this%model%fr%kappa, .true.)
      call real_field('fracture_time', centre_cell, 8, this%model%fr%t_fail, .true.)
      call real_field('fracture_energy', centre_cell, 1, this%model%fr%diss, .true.)
      call real_field('fracture_strain', centre_cell, 8, this%model%fr%e_prev, .true.)
    end if

  contains

    !> The reactions, kept per prescribed dof (model%r_bc), travel as the node field
    !> 'reaction' of width 2 (f_int - f_ext of each prescribed component, 0 at free dofs): at
    !> op_out the model's dofs are those of the lattice the registry was copied out to.
    subroutine reaction_field()
      real(wp), pointer, contiguous :: p(:)
      integer :: id, q
      if (stat /= 0) return
      if (op == op_register .or. op == op_borrow) then
        call reg%add('reaction', centre_node, kind_real, 2, id, stat)
        if (op == op_register .or. stat /= 0) return
      end if
      id = reg%find('reaction')
      if (id == 0 .or. .not. allocated(this%model%r_bc)) return
      p => reg%real_flat(id)
      associate(m => this%model)
        if (op /= op_out) then
          p = 0.0_wp
          do q = 1, size(m%bc_node)
            p(m%bc_comp(q) + 2*(m%bc_node(q) - 1)) = m%r_bc(q)
          end do
        else
          do q = 1, size(m%bc_node)
            m%r_bc(q) = p(m%bc_comp(q) + 2*(m%bc_node(q) - 1))
          end do
        end if
      end associate
    end subroutine reaction_field

    !> Register, copy in or copy out one real field whose run's array is a (rank 1 or 2; not
    !> referenced when registering, so it may be unallocated then), or register it borrowed.
    subroutine real_field(name, centre, width, a, checkpointed)
      character(len=*), intent(in) :: name
      integer, intent(in) :: centre, width
      real(wp), allocatable, intent(inout), target :: a(..)
      logical, intent(in) :: checkpointed
      real(wp), pointer, contiguous :: p(:)
      integer :: id
      if (stat /= 0) return
      if (checkpoint .and. .not. checkpointed) return
      if (op == op_borrow .and. allocated(a)) then
        if (spans(width, centre, size(a, kind=i8))) then
          select rank (a)
          rank (1)
            p => a
          rank (2)
            p(1:size(a)) => a
          end select
          call reg%borrow_real(name, centre, width, p, id, stat)
          return
        else if (size(a) == 0) then
          ! (an array without columns, fused RK4's rates: zeros in a checkpoint, no copy)
          call reg%add_zeros(name, centre, kind_real, width, id, stat)
          return
        end if
      end if
      call copied(name, centre, kind_real, width, id)
      if (id == 0 .or. .not. allocated(a)) return
      p => reg%real_flat(id)
      select rank (a)
      rank (1)
        if (op /= op_out) then
          p(1:size(a)) = a
        else
          a = p(1:size(a))
        end if
      rank (2)
        if (op /= op_out) then
          ! (an array without columns, fused RK4's rates: zeros in a checkpoint)
          if (size(a) == 0) p = 0.0_wp
          p(1:size(a)) = reshape(a, [size(a)])
        else
          a = reshape(p(1:size(a)), shape(a))
        end if
      end select
    end subroutine real_field

    !> Register, copy in or copy out one integer field whose run's array is a (rank 1), or
    !> register it borrowed.
    subroutine int_field(name, centre, width, a, checkpointed)
      character(len=*), intent(in) :: name
      integer, intent(in) :: centre, width
      integer(ip), allocatable, intent(inout), target :: a(:)
      logical, intent(in) :: checkpointed
      integer(ip), pointer, contiguous :: p(:)
      integer :: id
      if (stat /= 0) return
      if (checkpoint .and. .not. checkpointed) return
      if (op == op_borrow .and. allocated(a)) then
        if (spans(width, centre, size(a, kind=i8))) then
          call reg%borrow_int(name, centre, width, a, id, stat)
          return
        end if
      end if
      call copied(name, centre, kind_int, width, id)
      if (id == 0 .or. .not. allocated(a)) return
      p => reg%int_flat(id)
      if (op /= op_out) then
        p(1:size(a)) = a
      else
        a = p(1:size(a))
      end if
    end subroutine int_field

    !> A field the registry holds a copy of: with op_register or op_borrow, add it (owned) to
    !> reg; then its id when there are values to copy in or out (op_in, op_out, op_borrow),
    !> else 0 (registering alone, a failed add, not in reg, or not the registry's own).
    subroutine copied(name, centre, kind, width, id)
      character(len=*), intent(in) :: name
      integer, intent(in) :: centre, kind, width
      integer, intent(out) :: id
      if (op == op_register .or. op == op_borrow) then
        call reg%add(name, centre, kind, width, id, stat)
        if (op == op_register .or. stat /= 0) id = 0
        if (id == 0) return
      end if
      id = reg%find(name)
      if (id /= 0) then
        if (.not. reg%owns(id)) id = 0
      end if
    end subroutine copied

    !> Whether a run's array of n values holds width values of every entity of a centre of
    !> reg (and so can be borrowed).
    pure logical function spans(width, centre, n)
      integer, intent(in) :: width, centre
      integer(i8), intent(in) :: n
      spans = n == int(width, i8)*reg%n_of(centre)
    end function spans
  end subroutine each_field
end submodule iem_simulation_fields
