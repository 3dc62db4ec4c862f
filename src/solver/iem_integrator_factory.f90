!> The factory of the time integrators: the one place that maps &run integrator to a type.
module iem_integrator_factory
  use mpi_f08, only: MPI_Comm
  use iem_integrator, only: integrator_t
  use iem_rk4, only: rk4_t
  use iem_verlet, only: verlet_t
  implicit none
  private
  public :: integrator_create

contains

  !> Make the integrator named by &run integrator ('verlet': velocity Verlet; otherwise RK4,
  !> the default), agreeing on its steps over comm.
  subroutine integrator_create(kind, comm, integ)
    character(len=*), intent(in) :: kind
    type(MPI_Comm), intent(in) :: comm
    class(integrator_t), allocatable, intent(out) :: integ
    if (kind == 'verlet') then
      allocate(verlet_t :: integ)
    else
      allocate(rk4_t :: integ)
    end if
    call integ%init(comm)
  end subroutine integrator_create
end module iem_integrator_factory
