!> Failed allocations of problem-sized arrays turned into one message and an agreed status:
!> each rank notes the stat= of its allocations, and at the next collective point every rank
!> learns whether any failed (and which, first), so that all stop together without a hang.
!>
!>     allocate(part(0:n - 1), stat=ierr)
!>     call guard%note(ierr, 'the partition of the whole body', 4.0_wp*n)
!>     if (guard%failed) ... skip to the collective point ...
!>     call guard%agree(comm, label, stat, msg)   ! collective
module iem_alloc_guard
  use mpi_f08, only: MPI_Comm, MPI_Comm_rank, MPI_Allreduce, MPI_Bcast, MPI_MIN, &
                     MPI_INTEGER, MPI_CHARACTER, MPI_IN_PLACE
  use iem_kinds, only: wp, mpi_wp
  use iem_strings, only: itoa
  use iem_memory, only: bytes_text
  implicit none
  private
  public :: alloc_guard_t

  !> The first failed allocation of this rank since the guard was made or last agreed.
  type :: alloc_guard_t
    logical :: failed = .false.
    character(len=96) :: what = ''
    real(wp) :: bytes = 0.0_wp
  contains
    procedure :: note => alloc_guard_note
    procedure :: agree => alloc_guard_agree
    procedure :: pass => alloc_guard_pass
  end type alloc_guard_t

contains

  !> Note the stat= of an allocation of about bytes bytes that holds what.
  subroutine alloc_guard_note(this, ierr, what, bytes)
    class(alloc_guard_t), intent(inout) :: this
    integer, intent(in) :: ierr
    character(len=*), intent(in) :: what
    real(wp), intent(in) :: bytes
    if (ierr == 0 .or. this%failed) return
    this%failed = .true.
    this%what = what
    this%bytes = bytes
  end subroutine alloc_guard_note

  !> Hand a failure on to the caller's guard to (kept if it holds one already); where the
  !> caller gave none (tests, tools), a failure stops the program.
  subroutine alloc_guard_pass(this, to)
    class(alloc_guard_t), intent(in) :: this
    type(alloc_guard_t), intent(inout), optional :: to
    if (.not. this%failed) return
    if (present(to)) then
      if (.not. to%failed) to = this
    else
      error stop 'iem: out of memory allocating '//trim(this%what)
    end if
  end subroutine alloc_guard_pass

  !> Collective: stat = 1 on every rank when an allocation failed on any rank, with msg
  !> (the same on every rank) naming label, what failed, its size and the lowest such rank;
  !> stat = 0 otherwise. The guard is cleared.
  subroutine alloc_guard_agree(this, comm, label, stat, msg)
    class(alloc_guard_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: rank, first
    call MPI_Comm_rank(comm, rank)
    first = huge(1)
    if (this%failed) first = rank
    call MPI_Allreduce(MPI_IN_PLACE, first, 1, MPI_INTEGER, MPI_MIN, comm)
    stat = 0
    msg = ''
    if (first /= huge(1)) then
      call MPI_Bcast(this%what, len(this%what), MPI_CHARACTER, first, comm)
      call MPI_Bcast(this%bytes, 1, mpi_wp(), first, comm)
      stat = 1
      msg = label//': out of memory on rank '//itoa(first)//': allocating '// &
            trim(this%what)//' ('//bytes_text(this%bytes)//') failed; use more nodes, '// &
            'fewer ranks a node, or a coarser grid (docs/input.md, Limits)'
    end if
    this%failed = .false.
    this%what = ''
    this%bytes = 0.0_wp
  end subroutine alloc_guard_agree
end module iem_alloc_guard
