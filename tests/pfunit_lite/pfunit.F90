!> pfunit_lite, MPI part: a small stand-in for pFUnit 4's `pfunit` module.
!> Re-exports everything public in funit and, like pFUnit's `pfunit`, everything of the `mpi`
!> module (so that importing the same names from mpi_f08 is an ambiguous reference here
!> too), and adds MpiTestMethod and the MPI test runner.
module pfunit
  use funit
  use mpi
  implicit none
  public

  !> What an MPI test receives as `this`: its communicator, its rank and its size.
  type :: MpiTestMethod
    private
    integer :: comm = 0
    integer :: rank = 0
    integer :: npes = 1
  contains
    procedure :: getMpiCommunicator
    procedure :: getProcessRank
    procedure :: getNumProcesses
  end type MpiTestMethod

  abstract interface
    !> An MPI test or fixture: pFUnit's interface, which the test procedures must match.
    subroutine pfl_mpi_method(this)
      import :: MpiTestMethod
      class(MpiTestMethod), intent(inout) :: this
    end subroutine pfl_mpi_method
  end interface
  private :: pfl_mpi_method, getMpiCommunicator, getProcessRank, getNumProcesses

contains

  !> The communicator of the test (an `use mpi` style integer handle).
  integer function getMpiCommunicator(this) result(comm)
    class(MpiTestMethod), intent(in) :: this
    comm = this%comm
  end function getMpiCommunicator

  !> The rank of this process in the test's communicator.
  integer function getProcessRank(this) result(rank)
    class(MpiTestMethod), intent(in) :: this
    rank = this%rank
  end function getProcessRank

  !> The number of processes in the test's communicator.
  integer function getNumProcesses(this) result(npes)
    class(MpiTestMethod), intent(in) :: this
    npes = this%npes
  end function getNumProcesses

  !> Runs an MPI test once for each size in npes (0: all ranks), on the first npes ranks of
  !> MPI_COMM_WORLD (made with MPI_Comm_split): setUp, then (unless setUp failed on a rank of
  !> the test) the test and tearDown. A size larger than the world fails, as in pFUnit.
  subroutine pfl_run_mpi(name, npes, test, setUp, tearDown)
    character(len=*), intent(in) :: name
    integer, intent(in) :: npes(:)
    procedure(pfl_mpi_method) :: test
    procedure(pfl_mpi_method), optional :: setUp, tearDown
    type(MpiTestMethod) :: this
    character(len=:), allocatable :: full_name
    integer :: j, n, world_rank, world_size, comm, ierr

    call MPI_Comm_rank(MPI_COMM_WORLD, world_rank, ierr)
    call MPI_Comm_size(MPI_COMM_WORLD, world_size, ierr)
    do j = 1, size(npes)
      n = npes(j)
      if (n == 0) n = world_size
      full_name = name // '[npes=' // pfl_str(n) // ']'
      if (n > world_size) then
        call pfl_fail_test(full_name, 'Insufficient processes to run this test (needs ' // &
            pfl_str(n) // ', the run has ' // pfl_str(world_size) // ')')
        cycle
      end if
      call MPI_Comm_split(MPI_COMM_WORLD, merge(0, MPI_UNDEFINED, world_rank < n), &
          world_rank, comm, ierr)
      if (world_rank >= n) cycle
      this = MpiTestMethod(comm=comm, rank=world_rank, npes=n)
      call pfl_begin_test(full_name)
      if (present(setUp)) call setUp(this)
      if (.not. anyExceptions(comm)) then
        call test(this)
        if (present(tearDown)) call tearDown(this)
      end if
      call pfl_end_test(comm)
      call MPI_Comm_free(comm, ierr)
    end do
  end subroutine pfl_run_mpi

end module pfunit
